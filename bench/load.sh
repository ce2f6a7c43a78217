#!/usr/bin/env bash
# load.sh [BUILD_DIR]: the load run of ipsd (prints figures, never pass/fail on time).
#   1. starts BUILD_DIR/server/ipsd (default build/; this script builds nothing) on a free
#      loopback port with a temporary database, 2 fit workers;
#   2. seeds a sensor and the calibration of the pixel the readers read (a fit of an uploaded
#      scan file), then queues FITS (300) more fits of a dense uploaded scan (29 x 29 points in
#      0.2 um steps, made by `ips simulate`; ~0.1 s each) to run in the background;
#   3. runs wrk (-t2 -c32 -d10s --latency) on GET /api/sensors/1/pixels/10/10/calibration while
#      the fits run, and prints reads per second, p50/p99 latency and how many fits finished;
#   4. times storing a full 51 x 51 scan (BUILD_DIR/bench/ipsd-bench-store).
# Needs wrk, curl and python3 (Debian packages). Environment: FITS, DURATION (10s), CONNS (32).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "${1:-$root/build}" && pwd)
ipsd=$build/server/ipsd
ips=$build/cli/ips
store=$build/bench/ipsd-bench-store
FITS=${FITS:-300}
DURATION=${DURATION:-10s}
CONNS=${CONNS:-32}
for tool in wrk curl python3; do
    command -v $tool >/dev/null || { echo "load.sh: needs $tool (apt-get install $tool)" >&2; exit 1; }
done
[[ -x $ipsd && -x $ips ]] || { echo "load.sh: no $ipsd or $ips (build first)" >&2; exit 1; }

tmp=$(mktemp -d "${TMPDIR:-/tmp}/ipsd-load-XXXXXX")
pid=
cleanup() {
    [[ -n $pid ]] && kill "$pid" 2>/dev/null && wait "$pid" 2>/dev/null
    rm -rf "$tmp"
}
trap cleanup EXIT

"$ipsd" --listen 127.0.0.1:0 --port-file "$tmp/port" --db "$tmp/ipsd.db" --workers 2 \
    >"$tmp/ipsd.log" 2>&1 &
pid=$!
for _ in $(seq 100); do [[ -s $tmp/port ]] && break; sleep 0.05; done
port=$(cat "$tmp/port")
base=http://127.0.0.1:$port
echo "ipsd on $base ($(nproc) CPUs), database in $tmp"

"$ips" simulate --grid 29 --step 0.2 -o "$tmp/dense.json" >/dev/null
python3 - "$base" "$root/tests/data/paperlike_scan.json" "$tmp/dense.json" "$FITS" <<'PY'
# seeds the sensor and the read pixel's calibration, then queues the background fits
import http.client, json, sys, time, urllib.parse
base, ref, dense, n = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
c = http.client.HTTPConnection(urllib.parse.urlparse(base).netloc)
def post(path, body):
    c.request("POST", path, json.dumps(body), {"Content-Type": "application/json"})
    r = c.getresponse()
    data = json.loads(r.read())
    if r.status >= 300: sys.exit("load.sh: %s -> %d %s" % (path, r.status, data))
    return data
def get(path):
    c.request("GET", path); r = c.getresponse(); return json.loads(r.read())
sensor = post("/api/sensors", {"model": "LOAD", "serial": "1"})["id"]
job = post("/api/fits", {"scan": json.load(open(ref)), "sensor_id": sensor,
                         "pixel": {"col": 10, "row": 10}})["job"]["id"]
while get("/api/jobs/%d" % job)["state"] != "done": time.sleep(0.05)
scan = json.load(open(dense))
t = time.time()
for i in range(n):
    post("/api/fits", {"scan": scan, "sensor_id": sensor, "pixel": {"col": 20 + i % 50, "row": 20},
                       "ftest": "top,left,bottom", "wiener": True})
print("queued %d background fits (%d points each) in %.1f s" % (n, len(scan["x_um"]), time.time() - t))
PY

done_fits() { curl -s "$base/api/jobs?kind=fit&state=done&limit=1" | python3 -c 'import json,sys; print(json.load(sys.stdin)["total"])'; }
before=$(done_fits)
url="$base/api/sensors/1/pixels/10/10/calibration"
curl -sf "$url" >/dev/null
wrk -t2 -c"$CONNS" -d"$DURATION" --latency "$url" >"$tmp/wrk.txt"
after=$(done_fits)
queued=$(curl -s "$base/api/jobs?kind=fit&state=queued&limit=1" | python3 -c 'import json,sys; print(json.load(sys.stdin)["total"])')
echo "== calibration reads (wrk -t2 -c$CONNS -d$DURATION) with fits running in the background"
sed -n '/Latency Distribution/,/99%/p;/Requests\/sec/p;/requests in/p;/Non-2xx/p;/Socket errors/p' "$tmp/wrk.txt"
python3 - "$tmp/wrk.txt" "$before" "$after" "$queued" <<'PY'
import re, sys
text = open(sys.argv[1]).read()
def lat(tag):
    m = re.search(r"^\s*%s\s+([\d.]+)(us|ms|s)\s*$" % tag, text, re.M)
    return float(m.group(1)) * {"us": 1e-3, "ms": 1, "s": 1e3}[m.group(2)] if m else float("nan")
rps = float(re.search(r"Requests/sec:\s+([\d.]+)", text).group(1))
done = int(sys.argv[3]) - int(sys.argv[2])
print("summary: %.0f reads/s, p50 %.2f ms, p99 %.2f ms; %d fits finished during the run, %s "
      "still queued (target: >= 5000 reads/s, p99 < 10 ms)" % (rps, lat("50%"), lat("99%"), done, sys.argv[4]))
PY
kill "$pid"
wait "$pid" || true
pid=

echo "== storing a full 51 x 51 scan"
if [[ -x $store ]]; then "$store" "$tmp"; else echo "(no $store)"; fi
