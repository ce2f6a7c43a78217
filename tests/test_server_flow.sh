#!/usr/bin/env bash
# test_server_flow.sh IPSD IPS: the full path through a real ipsd (simulated bench) with a real
# HTTP client: create a sensor, submit a small simulated scan, follow it to done (and over the
# event stream), get the automatic fit, read the calibration back as JSON and CSV, and check the
# map against `ips fit` run on the pixel raster downloaded from the API (the independent path: the
# command-line tool over the scan-file contract) and against the database read by Python's
# sqlite3 module. Then a fit of another pixel with other options, a fit of an uploaded scan file
# that supersedes the first calibration (history), the search, and a graceful stop.
source "$(dirname "$0")/test_server_lib.sh"
setup "$1" "$2"
start

curl -sN --max-time 90 "http://127.0.0.1:$PORT/api/events" >"$T/events" &
SSE=$!

req POST /api/sensors '{"model": "IMX-T", "serial": "flow-1", "n_cols": 128, "n_rows": 96}'
expect_status 201 "create sensor"
SENSOR=$(js "d['id']")
req GET "/api/sensors/$SENSOR"
check "sensor read back" -- test "$(js "d['n_cols'], d['pitch_um'], d['serial']")" == "(128, 6.0, 'flow-1')"

# 3 x 3 pixels in 0.6 um steps: 31 x 31 points, 9 x 9 of them inside the POI (enough for r = 8)
SCAN_REQ='{"sensor_id": '$SENSOR', "poi": {"col": 50, "row": 60},
           "raster": {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}, "seed": 7}'
req POST /api/scans "$SCAN_REQ"
expect_status 202 "submit scan"
SCAN=$(js "d['scan']['id']")
JOB=$(js "d['job']['id']")
check "scan answer: 961 points planned" -- test "$(js "d['scan']['raster']['points_total']")" == 961
# the job row was committed before the answer
check "job row exists at once" -- test "$(sql "SELECT count(*) FROM jobs WHERE id = $JOB")" == 1

check "scan job done" -- wait_job "$JOB" done 60
req GET "/api/scans/$SCAN"
check "scan done, every point" -- test "$(js "d['state'], d['points_done'], d['job_id']")" == "('done', 961, $JOB)"
check "setup stored" -- test "$(js "d['setup']['pitch_um']")" == 6.0
check "961 frame rows" -- test "$(sql "SELECT count(*) FROM frames WHERE scan_id = $SCAN")" == 961

# the automatic fit of the POI
req GET "/api/jobs?kind=fit&scan=$SCAN"
check "one automatic fit job" -- test "$(js "d['total']")" == 1
FITJOB=$(js "d['items'][0]['id']")
check "automatic fit done" -- wait_job "$FITJOB" done 60
FIT=$(js "d['fit_id']")
check "fit job params: paper's F-test, Wiener" -- test \
    "$(js "d['params']['ftest'], d['params']['ftest_r'], d['params']['wiener'], d['params']['r_max']")" \
    == "('top,left,bottom', 7, True, 8)"

# the pixel raster as a scan file, fitted by ips fit with the same options
req GET "/api/scans/$SCAN/pixels/0/0"
expect_status 200 "pixel raster"
printf '%s' "$BODY" >"$T/pixel.json"
check "pixel raster: 81 points inside" -- test "$(js "len(d['x_um'])")" == 81
"$IPS" fit "$T/pixel.json" --ftest top,left,bottom --wiener >"$T/ips.json"
ok $? "ips fit on the downloaded raster"

req GET "/api/sensors/$SENSOR/pixels/50/60/calibration"
expect_status 200 "calibration JSON"
printf '%s' "$BODY" >"$T/calib.json"
curl -s "$BASE/api/sensors/$SENSOR/pixels/50/60/calibration?format=csv" >"$T/calib.csv"
curl -s -H 'Accept: text/csv' "$BASE/api/sensors/$SENSOR/pixels/50/60/calibration" >"$T/calib2.csv"
check "Accept: text/csv gives the same CSV" -- cmp -s "$T/calib.csv" "$T/calib2.csv"
req GET "/api/fits/$FIT"
printf '%s' "$BODY" >"$T/fit.json"

python3 - "$T" "$SCAN" <<'PY'
import csv, json, sqlite3, struct, sys
t, scan = sys.argv[1], int(sys.argv[2])
ips = json.load(open(t + "/ips.json"))
cal = json.load(open(t + "/calib.json"))
fit = json.load(open(t + "/fit.json"))
bic = ips["best_r"]["bic"]
best = [f for f in ips["fits"] if f["r"] == bic][0]
fails = []
def near(a, b, what):
    if len(a) != len(b) or any(abs(x - y) > 1e-9 for x, y in zip(a, b)):
        fails.append(what)
if cal["r"] != bic: fails.append("calibration r %d != ips fit best BIC r %d" % (cal["r"], bic))
near(cal["S"], best["S"], "S vs ips fit")
near(cal["S_err"], best["S_err"], "S_err vs ips fit")
if abs(cal["I0"] - best["I0"]) > 1e-9 * abs(best["I0"]): fails.append("I0")
if cal["status"] != best["status"] or cal["scan_id"] != scan: fails.append("status/provenance")
if fit["best_r"] != ips["best_r"]: fails.append("fit best_r")
# the stored document follows the `ips fit` schema: the same fits, key for key (timing aside)
strip = lambda f: {k: v for k, v in f.items() if k != "timing_ms"}
if [strip(f) for f in fit["result"]["fits"]] != [strip(f) for f in ips["fits"]]:
    fails.append("stored fits[] differ from ips fit's")
for k in ("N", "n_points", "sigma", "method", "nonneg", "design_tol", "full_scale_dn", "best_r"):
    if fit["result"][k] != ips[k]: fails.append("result." + k)
if abs(fit["result"]["ftest"]["F"] - ips["ftest"]["F"]) > 1e-9 * ips["ftest"]["F"]: fails.append("F")
near(fit["result"]["wiener"]["S"], ips["wiener"]["S"], "Wiener S")
# CSV: one line per sub-pixel, row-major j*r + i
rows = list(csv.DictReader(open(t + "/calib.csv")))
if len(rows) != bic * bic: fails.append("CSV lines")
near([float(r["S"]) for r in rows], [best["S"][int(r["j"]) * bic + int(r["i"])] for r in rows], "CSV S")
# the database, read by Python's sqlite3 (little-endian float64 BLOBs, docs/schema.md)
db = sqlite3.connect(t + "/ipsd.db")
r, s = db.execute("SELECT r, s FROM calibrations WHERE pixel_col = 50 AND pixel_row = 60 "
                  "AND superseded_by IS NULL").fetchone()
near(struct.unpack("<%dd" % (r * r), s), best["S"], "database S")
for f in fails: print("FAIL:", f)
sys.exit(1 if fails else 0)
PY
ok $? "stored calibration = ips fit on the downloaded raster (JSON, CSV, database)"

# the event stream saw the scan run (progress, ETA) and both jobs finish
kill "$SSE" 2>/dev/null
wait "$SSE" 2>/dev/null
python3 - "$T/events" "$JOB" "$FITJOB" <<'PY'
import json, sys
ev = [json.loads(l[6:]) for l in open(sys.argv[1]) if l.startswith("data: ")]
job, fitjob = int(sys.argv[2]), int(sys.argv[3])
run = [e for e in ev if e["id"] == job and e["state"] == "running" and e["phase"] == "raster"]
ok = (len(run) > 10 and all(e["points_total"] == 961 for e in run)
      and any(e["eta_s"] is not None and e["points_done"] > 0 for e in run)
      and any(e["id"] == job and e["state"] == "done" for e in ev)
      and any(e["id"] == fitjob and e["state"] == "done" for e in ev)
      and sorted(e["points_done"] for e in run) == [e["points_done"] for e in run])
if not ok: print("events:", ev[:3], len(ev))
sys.exit(0 if ok else 1)
PY
ok $? "SSE: running progress with ETA, then done, for the scan and its fit"
grep -q '^: heartbeat' "$T/events"
ok $? "SSE heartbeat comment"
# ?job=ID: the job's current state first, then only its events
curl -sN --max-time 1.5 "$BASE/api/events?job=$JOB" >"$T/events1"
check "SSE ?job: its current state first" -- test \
    "$(sed -n 's/^data: //p' "$T/events1" | head -1 | python3 -c 'import json,sys; d=json.load(sys.stdin); print(d["id"], d["state"], d["points_done"], d["points_total"])')" \
    == "$JOB done 961 961"
grep -q '^retry: 3000' "$T/events1"
ok $? "SSE retry hint"

# a fit of another pixel with other options
req POST "/api/scans/$SCAN/fits" '{"dcol": 1, "drow": 0, "r_min": 1, "r_max": 4, "sigma": "shot+read"}'
expect_status 202 "fit another pixel"
J2=$(js "d['job']['id']")
check "second fit done" -- wait_job "$J2" done 60
curl -s "$BASE/api/scans/$SCAN/pixels/1/0" >"$T/pixel10.json"
"$IPS" fit "$T/pixel10.json" --r-min 1 --r-max 4 --sigma shot+read >"$T/ips10.json"
req GET "/api/sensors/$SENSOR/pixels/51/60/calibration"
printf '%s' "$BODY" >"$T/calib10.json"
python3 - "$T" <<'PY'
import json, sys
t = sys.argv[1]
ips, cal = json.load(open(t + "/ips10.json")), json.load(open(t + "/calib10.json"))
best = [f for f in ips["fits"] if f["r"] == ips["best_r"]["bic"]][0]
sys.exit(0 if cal["r"] == best["r"] and cal["noise_model"] == "shot+read" and
         max(abs(a - b) for a, b in zip(cal["S"], best["S"])) < 1e-9 else 1)
PY
ok $? "pixel (+1, 0) fitted with shot+read, r <= 4, = ips fit"

# an uploaded scan file (the same pixel's data) becomes the new calibration of (50, 60)
python3 -c "
import json; s = json.load(open('$T/pixel.json'))
print(json.dumps({'scan': s, 'sensor_id': $SENSOR, 'pixel': {'col': 50, 'row': 60},
                  'optics': {'wavelength_nm': 550, 'na': 0.25}, 'ftest': 'top,left,bottom',
                  'wiener': True}))" >"$T/upload.json"
req POST /api/fits "$(cat "$T/upload.json")"
expect_status 202 "upload fit"
J3=$(js "d['job']['id']")
check "upload fit done" -- wait_job "$J3" done 60
F3=$(js "d['fit_id']")
req GET "/api/fits/$F3"
check "upload fit has no scan" -- test "$(js "d['scan_id']")" == None
req GET "/api/sensors/$SENSOR/pixels/50/60/history"
check "history: two maps, newest first, the old one superseded" -- test \
    "$(js "len(d['items']), d['items'][0]['current'], d['items'][1]['superseded_by'] == d['items'][0]['id'], d['items'][0]['S'] == d['items'][1]['S']")" \
    == "(2, True, True, True)"
R=$(js "d['items'][0]['r']")
check "history CSV lines" -- test "$(curl -s "$BASE/api/sensors/$SENSOR/pixels/50/60/history?format=csv" | wc -l)" == $((2 * R * R + 1))
req GET "/api/calibrations?sensor=$SENSOR&current=1"
check "search: two current maps" -- test "$(js "d['total']")" == 2
req GET "/api/calibrations?sensor=$SENSOR"
check "search: three maps in all" -- test "$(js "d['total']")" == 3
req GET "/api/scans?sensor=$SENSOR&state=done"
check "scan list filter" -- test "$(js "d['total'], d['items'][0]['id']")" == "(1, $SCAN)"
req GET "/api/scans/$SCAN/points/480"
check "a point's frames: 2 raw 3x3 frames" -- test "$(js "len(d['raw']), len(d['raw'][0]), len(d['mean'])")" == "(2, 9, 9)"

stop_term
ok $? "SIGTERM: exit status 0"
grep -q "ipsd: stopped" "$T/ipsd.log"
ok $? "graceful stop logged"
finish
