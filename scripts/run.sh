#!/usr/bin/env bash
# run.sh: installs what is missing (Debian packages, the dashboard's Plotly.js), builds ipsd, and
# runs the main job: the ipsd server on the simulated bench with its database in var/ipsd.db,
# one paper-like scan of a pixel queued (the paper's raster: 5 x 5 pixels in 0.6 um steps, 9 x 9
# sub-frames, 12 frames per point), then the automatic fit of that pixel. Prints the dashboard's
# URL and how to follow the job with curl, and keeps ipsd in the foreground until Ctrl-C (a
# graceful stop: a scan still running resumes at the next start). It says when the scan and its
# fit end and what the fit found (scripts/run_follow.py). At the next start it queues no second
# scan of the same pixel: it follows the scan still running, or shows the pixel's calibration
# (IPSD_NEW_SCAN=1 queues a new scan).
#   scripts/run.sh [ipsd options...]   e.g. --workers 4, --token FILE
#   scripts/run.sh --fit-only          the former main job: `ips fit` of the reference scan as a table
# Environment: IPSD_LISTEN (default 127.0.0.1:8080), IPSD_POI (default 128,128), IPSD_BUILD (the
# build directory, default build).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
scripts/deps.sh
build=${IPSD_BUILD:-build}
scripts/build.sh "$build"

if [[ ${1:-} == --fit-only ]]; then
    exec "$build"/cli/ips fit tests/data/paperlike_scan.json --ftest top,left,bottom --wiener --table
fi
# the dashboard's plotting library (Plotly.js from web/package-lock.json), served by ipsd
scripts/web-deps.sh

listen=${IPSD_LISTEN:-127.0.0.1:8080}
poi=${IPSD_POI:-128,128}
mkdir -p var
rm -f var/ipsd.port
"$build"/server/ipsd --listen "$listen" --db var/ipsd.db --bench sim --port-file var/ipsd.port "$@" &
pid=$!
# Ctrl-C (SIGINT to the whole process group) or a kill of this script: ipsd stops gracefully and
# this script waits for it
trap 'kill -TERM $pid 2>/dev/null' INT TERM
for _ in $(seq 100); do
    [[ -s var/ipsd.port ]] && break
    kill -0 $pid 2>/dev/null || { wait $pid; exit $?; }
    sleep 0.1
done
host=${listen%:*}
base="http://$host:$(cat var/ipsd.port)"
curl -sf "$base/api/health" >/dev/null || { echo "run.sh: ipsd does not answer on $base" >&2; exit 1; }

# writes need the token when ipsd runs with --token FILE
auth=()
for ((i = 1; i <= $#; i++)); do
    if [[ ${!i} == --token ]]; then
        j=$((i + 1))
        auth=(-H "Authorization: Bearer $(tr -d ' \t\r\n' <"${!j}")")
    fi
done

# the simulated bench's sensor (the paper's: 6 um pixels, 14 bit), created once, then reused
sensor=$(curl -sf "$base/api/sensors" | python3 -c '
import json, sys
ids = [s["id"] for s in json.load(sys.stdin)["items"] if (s["model"], s["serial"]) == ("SIM-PAPER", "bench-1")]
print(ids[0] if ids else "")')
if [[ -z $sensor ]]; then
    sensor=$(curl -sf "${auth[@]}" -H 'Content-Type: application/json' "$base/api/sensors" \
        -d '{"model": "SIM-PAPER", "serial": "bench-1"}' | python3 -c 'import json,sys; print(json.load(sys.stdin)["id"])')
fi
col=${poi%,*}
row=${poi#*,}
# one scan per pixel: a scan of it still queued or running (resumed after a restart) is followed,
# a pixel already calibrated is shown; IPSD_NEW_SCAN=1 queues a new scan anyway
read -r picked scan_or_calib job_or_scan < <(python3 scripts/run_follow.py pick "$base" "$sensor" "$col" "$row")
if [[ ${IPSD_NEW_SCAN:-0} == 1 || $picked == none ]]; then
    answer=$(curl -s "${auth[@]}" -H 'Content-Type: application/json' "$base/api/scans" \
        -d '{"sensor_id": '"$sensor"', "poi": {"col": '"$col"', "row": '"$row"'}, "scene": "paperlike"}')
    read -r scan job < <(python3 -c 'import json,sys; d=json.load(sys.stdin); print(d["scan"]["id"], d["job"]["id"])' <<<"$answer") || {
        echo "run.sh: the scan was refused: $answer" >&2
        kill -TERM $pid
        wait $pid
        exit 1
    }
    what="Queued scan $scan (job $job) of pixel ($poi) of sensor $sensor; when it is done, the fit of
that pixel is queued automatically and stored as its calibration."
elif [[ $picked == calibrated ]]; then
    scan=$job_or_scan
    job=
    what="Pixel ($poi) of sensor $sensor is calibrated already (calibration $scan_or_calib, from scan
$scan): no new scan queued (IPSD_NEW_SCAN=1 scripts/run.sh queues one)."
else
    scan=$picked
    job=$scan_or_calib
    what="Scan $scan (job $job) of pixel ($poi) of sensor $sensor was queued before and goes on; when
it is done, the fit of that pixel is queued automatically and stored as its calibration."
fi

cat <<EOT

ipsd is running ($base, database var/ipsd.db, simulated bench).
$what

  Dashboard:        $base/
  The scan:         curl -s $base/api/scans/$scan
  Its jobs:         curl -s '$base/api/jobs?scan=$scan'
  Live progress:    curl -N $base/api/events
  The calibration:  curl -s $base/api/sensors/$sensor/pixels/$col/$row/calibration
  ... as CSV:       curl -s '$base/api/sensors/$sensor/pixels/$col/$row/calibration?format=csv'
  The pixel's raster for ips fit:
                    curl -s $base/api/scans/$scan/pixels/0/0 > pixel.json && $build/cli/ips fit pixel.json --table
  The API:          curl -s $base/api/openapi.json   (docs/api.md)

Ctrl-C stops ipsd gracefully.${job:+ Progress below.}
EOT
# says how the scan goes, when it ends, and what its fit found
follower=
if [[ -n $job ]]; then
    python3 scripts/run_follow.py follow "$base" "$scan" "$job" "$sensor" "$col" "$row" &
    follower=$!
fi
trap 'kill -TERM $pid 2>/dev/null; [[ -n $follower ]] && kill $follower 2>/dev/null' INT TERM
status=0
while kill -0 $pid 2>/dev/null; do
    wait $pid && status=0 || status=$?
done
[[ -n $follower ]] && kill $follower 2>/dev/null
exit $status
