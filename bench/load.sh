#!/usr/bin/env bash
# load.sh [BUILD_DIR]: the load run of ipsd (prints figures, never pass/fail on time).
#   1. starts BUILD_DIR/server/ipsd (default build/; this script builds nothing) on a free
#      loopback port with a temporary database, 2 fit workers, and seeds a sensor and the
#      calibration of the pixel the readers read (a fit of an uploaded scan file);
#   2. reads that calibration with wrk (-t2 -c32 -d10s --latency) from a quiet ipsd, then the
#      same bytes as a static file from nginx (2 workers, access log off) on the same machine,
#      and prints both rates and their ratio (target: ipsd at least 80 % of nginx);
#   3. queues FITS (300) more fits of a dense uploaded scan (29 x 29 points in 0.2 um steps, made
#      by `ips simulate`; ~0.1 s each) and reads again while they run: reads per second, p50/p99
#      latency and how many fits finished (target: p99 under 5 ms);
#   4. times storing a full 51 x 51 scan (BUILD_DIR/bench/ipsd-bench-store).
# Needs wrk, curl, python3 and, for the reference of step 2, nginx (Debian packages wrk, curl,
# python3, nginx-light; scripts/deps.sh installs them). Environment: FITS, DURATION (10s),
# CONNS (32), IPSD_ARGS (more ipsd options, e.g. "--access-log off"), STEPS (which of the steps
# 2, 3 and 4 to run: "234"), WRK_NICE (below).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=$(cd "${1:-$root/build}" && pwd)
ipsd=$build/server/ipsd
ips=$build/cli/ips
store=$build/bench/ipsd-bench-store
FITS=${FITS:-300}
DURATION=${DURATION:-10s}
CONNS=${CONNS:-32}
IPSD_ARGS=${IPSD_ARGS:-}
STEPS=${STEPS:-234}
# WRK_NICE=N runs step 3's wrk at nice N (e.g. -10, as root): on a machine others load, the
# client's own wait for a CPU is then not counted as ipsd's tail
wrk_nice=
[[ -n ${WRK_NICE:-} ]] && wrk_nice="nice -n $WRK_NICE"
for tool in wrk curl python3; do
    command -v $tool >/dev/null || { echo "load.sh: needs $tool (apt-get install $tool)" >&2; exit 1; }
done
[[ -x $ipsd && -x $ips ]] || { echo "load.sh: no $ipsd or $ips (build first)" >&2; exit 1; }
nginx_bin=$(command -v nginx || { [[ -x /usr/sbin/nginx ]] && echo /usr/sbin/nginx; } || true)

tmp=$(mktemp -d "${TMPDIR:-/tmp}/ipsd-load-XXXXXX")
pid=
npid=
cleanup() {
    [[ -n $pid ]] && kill "$pid" 2>/dev/null && wait "$pid" 2>/dev/null
    [[ -n $npid ]] && kill "$npid" 2>/dev/null && wait "$npid" 2>/dev/null
    rm -rf "$tmp"
}
trap cleanup EXIT

"$ipsd" --listen 127.0.0.1:0 --port-file "$tmp/port" --db "$tmp/ipsd.db" --workers 2 \
    $IPSD_ARGS >"$tmp/ipsd.log" 2>&1 &
pid=$!
for _ in $(seq 100); do [[ -s $tmp/port ]] && break; sleep 0.05; done
port=$(cat "$tmp/port")
base=http://127.0.0.1:$port
echo "ipsd on $base ($(nproc) CPUs), database in $tmp"

# one small HTTP client for the seeding and the queueing below
cat >"$tmp/client.py" <<'PY'
import http.client, json, sys, time, urllib.parse
c = http.client.HTTPConnection(urllib.parse.urlparse(sys.argv[1]).netloc)
def post(path, body):
    c.request("POST", path, json.dumps(body), {"Content-Type": "application/json"})
    r = c.getresponse()
    data = json.loads(r.read())
    if r.status >= 300: sys.exit("load.sh: %s -> %d %s" % (path, r.status, data))
    return data
def get(path):
    c.request("GET", path); r = c.getresponse(); return json.loads(r.read())
if sys.argv[2] == "seed":  # the sensor and the read pixel's calibration
    sensor = post("/api/sensors", {"model": "LOAD", "serial": "1"})["id"]
    job = post("/api/fits", {"scan": json.load(open(sys.argv[3])), "sensor_id": sensor,
                             "pixel": {"col": 10, "row": 10}})["job"]["id"]
    while get("/api/jobs/%d" % job)["state"] != "done": time.sleep(0.05)
else:  # queue N background fits of the dense scan
    scan, n = json.load(open(sys.argv[3])), int(sys.argv[4])
    t = time.time()
    for i in range(n):
        post("/api/fits", {"scan": scan, "sensor_id": 1, "pixel": {"col": 20 + i % 50, "row": 20},
                           "ftest": "top,left,bottom", "wiener": True})
    print("queued %d background fits (%d points each) in %.1f s"
          % (n, len(scan["x_um"]), time.time() - t))
PY
# the figures of one wrk output: reads/s, p50 ms, p99 ms
cat >"$tmp/figures.py" <<'PY'
import re, sys
text = open(sys.argv[1]).read()
def lat(tag):
    m = re.search(r"^\s*%s\s+([\d.]+)(us|ms|s)\s*$" % tag, text, re.M)
    return float(m.group(1)) * {"us": 1e-3, "ms": 1, "s": 1e3}[m.group(2)] if m else float("nan")
m = re.search(r"Requests/sec:\s+([\d.]+)", text)
print("%.0f %.2f %.2f" % (float(m.group(1)) if m else float("nan"), lat("50%"), lat("99%")))
PY
python3 "$tmp/client.py" "$base" seed "$root/tests/data/paperlike_scan.json"
url="$base/api/sensors/1/pixels/10/10/calibration"
mkdir -p "$tmp/www"
curl -sf "$url" -o "$tmp/www/calibration.json"
row() { printf '%-36s %10s %8s %8s\n' "$@"; }

if [[ $STEPS == *2* ]]; then
echo "== the same $(stat -c %s "$tmp/www/calibration.json") bytes from ipsd and from nginx" \
     "(wrk -t2 -c$CONNS -d$DURATION, no fits running)"
wrk -t2 -c"$CONNS" -d"$DURATION" --latency "$url" >"$tmp/wrk-quiet.txt"
read -r q_rps q_p50 q_p99 < <(python3 "$tmp/figures.py" "$tmp/wrk-quiet.txt")
row server reads/s "p50 ms" "p99 ms"
row "ipsd, GET .../calibration" "$q_rps" "$q_p50" "$q_p99"
if [[ -n $nginx_bin ]]; then
    nport=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
    {
        [[ $(id -u) == 0 ]] && echo "user root;" # its workers must read the private temp dir
        cat <<CONF
worker_processes 2;
daemon off;
pid $tmp/nginx.pid;
error_log $tmp/nginx-error.log;
events { worker_connections 1024; }
http {
    access_log off;
    client_body_temp_path $tmp/nginx-body;
    proxy_temp_path $tmp/nginx-proxy;
    fastcgi_temp_path $tmp/nginx-fastcgi;
    uwsgi_temp_path $tmp/nginx-uwsgi;
    scgi_temp_path $tmp/nginx-scgi;
    server {
        listen 127.0.0.1:$nport;
        root $tmp/www;
        location / { default_type application/json; }
    }
}
CONF
    } >"$tmp/nginx.conf"
    "$nginx_bin" -c "$tmp/nginx.conf" -p "$tmp" 2>"$tmp/nginx-start.log" &
    npid=$!
    nurl=http://127.0.0.1:$nport/calibration.json
    for _ in $(seq 100); do curl -sf "$nurl" -o /dev/null && break; sleep 0.05; done
    wrk -t2 -c"$CONNS" -d"$DURATION" --latency "$nurl" >"$tmp/wrk-nginx.txt"
    read -r n_rps n_p50 n_p99 < <(python3 "$tmp/figures.py" "$tmp/wrk-nginx.txt")
    kill "$npid"
    wait "$npid" 2>/dev/null || true
    npid=
    row "nginx, the same bytes as a file" "$n_rps" "$n_p50" "$n_p99"
    python3 -c 'import sys; print("summary: ipsd reads at %.0f %% of nginx (target: >= 80 %%)"
                % (100 * float(sys.argv[1]) / float(sys.argv[2])))' "$q_rps" "$n_rps"
else
    echo "(no nginx: apt-get install nginx-light for the static-file reference)"
fi
fi

if [[ $STEPS == *3* ]]; then

"$ips" simulate --grid 29 --step 0.2 -o "$tmp/dense.json" >/dev/null
python3 "$tmp/client.py" "$base" queue "$tmp/dense.json" "$FITS"
done_fits() { curl -s "$base/api/jobs?kind=fit&state=done&limit=1" | python3 -c 'import json,sys; print(json.load(sys.stdin)["total"])'; }
before=$(done_fits)
log_from=$(stat -c %s "$tmp/ipsd.log")
$wrk_nice wrk -t2 -c"$CONNS" -d"$DURATION" --latency "$url" >"$tmp/wrk.txt"
after=$(done_fits)
queued=$(curl -s "$base/api/jobs?kind=fit&state=queued&limit=1" | python3 -c 'import json,sys; print(json.load(sys.stdin)["total"])')
echo "== calibration reads (wrk -t2 -c$CONNS -d$DURATION) with fits running in the background"
sed -n '/Latency Distribution/,/99%/p;/Requests\/sec/p;/requests in/p;/Non-2xx/p;/Socket errors/p' "$tmp/wrk.txt"
read -r f_rps f_p50 f_p99 < <(python3 "$tmp/figures.py" "$tmp/wrk.txt")
secs=$(python3 -c 'import re,sys; m = re.search(r"requests in ([\d.]+)(ms|s|m)", open(sys.argv[1]).read()); print(float(m.group(1)) * {"ms": 1e-3, "s": 1, "m": 60}[m.group(2)] if m else 0)' "$tmp/wrk.txt")
fits=$((after - before))
# the trade-off in one line: the reads' tail against the fits' own throughput in the same window
echo "summary: $f_rps reads/s, p50 $f_p50 ms, p99 $f_p99 ms; $fits fits finished" \
     "during the run ($(python3 -c 'import sys; s = float(sys.argv[2]); print("%.0f" % (60 * int(sys.argv[1]) / s) if s else "?")' "$fits" "$secs") fits/min)," \
     "$queued still queued; load average $(cut -d' ' -f1-3 /proc/loadavg) (target: p99 < 5 ms)"
# the request log's time of each of those reads inside ipsd (its headers read to its reply
# sent): what the handlers, locks and SQLite add; the rest of wrk's latency is the wait for a
# CPU and in the socket queues
tail -c +"$((log_from + 1))" "$tmp/ipsd.log" | python3 -c '
import re, sys
ms = sorted(float(m.group(1)) for m in re.finditer(r" GET /api/sensors/1/pixels/10/10/calibration 200 \S+ ([\d.]+)ms", sys.stdin.read()))
if ms:
    p = lambda q: ms[min(len(ms) - 1, int(q * len(ms)))]
    print("inside ipsd (request log, %d reads): p50 %.3f ms, p99 %.3f ms, p99.9 %.3f ms, max %.1f ms"
          % (len(ms), p(0.5), p(0.99), p(0.999), ms[-1]))'
curl -s "$base/api/health" | python3 -c 'import json,sys; h = json.load(sys.stdin).get("calibration_cache"); h and print("calibration cache: %(hits)d hits, %(misses)d misses, %(entries)d entries, %(bytes)d bytes" % h)'
fi
kill "$pid"
wait "$pid" || true
pid=

[[ $STEPS == *4* ]] || exit 0

echo "== storing a full 51 x 51 scan"
if [[ -x $store ]]; then "$store" "$tmp"; else echo "(no $store)"; fi
