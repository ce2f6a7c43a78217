#!/usr/bin/env bash
# test_server_restart.sh IPSD: jobs survive restarts. A scan interrupted by kill -9 resumes at the
# next start and ends with every raster point stored exactly once (rows counted and indexes
# checked with the sqlite3 shell), and a crashed ipsd leaves no stale lock (a second ipsd on the
# same database is refused while the first runs); SIGTERM exits 0 and gives the running scan back to the queue;
# a fit left running by a crash runs again; cancel works on queued and running jobs (scans and
# fits) and is refused (409) for finished ones; a long fit stops between its steps at SIGTERM and
# runs again at the next start.
source "$(dirname "$0")/test_server_lib.sh"
setup "$1"

# points_stored SCAN: frame rows of a scan
points_stored() { sql "SELECT count(*) FROM frames WHERE scan_id = $1"; }
# wait_points SCAN N: until at least N points are stored
wait_points() {
    for _ in $(seq 600); do
        (($(points_stored "$1") >= $2)) && return 0
        sleep 0.02
    done
    return 1
}
# exactly_once SCAN TOTAL: rows, distinct indexes, min and max are TOTAL, TOTAL, 0, TOTAL - 1
exactly_once() {
    [[ $(sql "SELECT count(*), count(DISTINCT point_index), min(point_index), max(point_index)
              FROM frames WHERE scan_id = $1") == "$2|$2|0|$(($2 - 1))" ]]
}

start
# one ipsd per database: a second one on the same file refuses to start (it would requeue the
# first one's running jobs), naming the reason
"$IPSD" --listen 127.0.0.1:0 --db "$T/ipsd.db" 2>"$T/second.err"
check "a second ipsd on the same database exits 1" -- test $? == 1
grep -q "in use by another ipsd" "$T/second.err"
ok $? "the second ipsd says why: $(cat "$T/second.err")"
req POST /api/sensors '{"model": "IMX-R", "serial": "restart-1"}'
SENSOR=$(js "d['id']")
SMALL='{"sensor_id": '$SENSOR', "poi": {"col": 30, "row": 30},
        "raster": {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}}'

# ---- kill -9 in the middle of a scan ----
req POST /api/scans "$SMALL"
S1=$(js "d['scan']['id']")
J1=$(js "d['job']['id']")
check "scan 1 reaches 100 points" -- wait_points "$S1" 100
sql "SELECT hex(mean) FROM frames WHERE scan_id = $S1 AND point_index = 0" >"$T/p0.before"
stop_kill
N1=$(points_stored "$S1")
check "killed mid-scan" -- test "$N1" -lt 961
check "left running by the crash" -- test "$(sql "SELECT state FROM jobs WHERE id = $J1")" == running
start
check "resumed scan done" -- wait_job "$J1" done 60
check "every point exactly once after the crash" -- exactly_once "$S1" 961
check "points stored before the crash kept" -- \
    test "$(sql "SELECT hex(mean) FROM frames WHERE scan_id = $S1 AND point_index = 0")" == "$(cat "$T/p0.before")"
check "claimed twice" -- test "$(sql "SELECT attempts FROM jobs WHERE id = $J1")" == 2
grep -q "1 interrupted job(s) queued again" "$T/ipsd.log"
ok $? "start-up requeue logged"
req GET "/api/scans/$S1"
check "scan 1 done with 961 points" -- test "$(js "d['state'], d['points_done']")" == "('done', 961)"

# ---- SIGTERM in the middle of a scan: exit 0, the scan resumes at the next start ----
req POST /api/scans "${SMALL/\"row\": 30/\"row\": 40}"
S2=$(js "d['scan']['id']")
J2=$(js "d['job']['id']")
check "scan 2 reaches 100 points" -- wait_points "$S2" 100
stop_term
ok $? "SIGTERM mid-scan: exit status 0"
N2=$(points_stored "$S2")
check "stopped mid-scan" -- test "$N2" -lt 961
check "job given back: queued, claim not counted" -- \
    test "$(sql "SELECT state, attempts FROM jobs WHERE id = $J2")" == "queued|0"
check "scan stays running (to resume)" -- test "$(sql "SELECT state FROM scans WHERE id = $S2")" == running
check "points_done = rows" -- test "$(sql "SELECT points_done FROM scans WHERE id = $S2")" == "$N2"

# a fit job a crash left running (as the row looks after kill -9 during a fit)
sql "INSERT INTO jobs (kind, params, state, attempts, heartbeat_ms, created_ms, started_ms, scan_id)
     VALUES ('fit', '{\"scan_id\": $S1, \"dcol\": 0, \"drow\": 1, \"r_min\": 1, \"r_max\": 3}',
             'running', 1, 1, 1, 1, $S1)"
JF=$(sql "SELECT max(id) FROM jobs")
start
check "scan 2 resumed to done" -- wait_job "$J2" done 60
check "every point of scan 2 exactly once after SIGTERM" -- exactly_once "$S2" 961
check "interrupted fit ran again" -- wait_job "$JF" done 60
check "its calibration (pixel 30, 31) stored" -- \
    test "$(sql "SELECT count(*) FROM calibrations WHERE pixel_col = 30 AND pixel_row = 31")" == 1

# ---- cancel: a running scan and a queued one ----
LONG='{"sensor_id": '$SENSOR', "poi": {"col": 80, "row": 80},
       "raster": {"area_px": 5, "step_um": 0.6, "sub_px": 3, "frames": 1}}'
req POST /api/scans "$LONG"
S3=$(js "d['scan']['id']")
J3=$(js "d['job']['id']")
req POST /api/scans "${LONG/\"row\": 80/\"row\": 90}"
S4=$(js "d['scan']['id']")
J4=$(js "d['job']['id']")
check "scan 3 running" -- wait_points "$S3" 20
req POST "/api/scans/$S4/cancel"
expect_status 200 "cancel a queued scan"
check "queued scan cancelled" -- test "$(js "d['scan']['state'], d['job']['state']")" == "('cancelled', 'cancelled')"
req POST "/api/scans/$S4/cancel"
expect_error 409 "" "cancel it again"
req POST "/api/jobs/$J3/cancel"
expect_status 200 "cancel the running scan's job"
check "running job cancelled" -- wait_job "$J3" cancelled 10
sleep 0.3
N3=$(points_stored "$S3")
sleep 0.3
check "no point stored after the cancel" -- test "$(points_stored "$S3")" == "$N3"
check "cancelled scan stopped short" -- test "$N3" -lt 2601
check "scan 3 cancelled" -- test "$(sql "SELECT state FROM scans WHERE id = $S3")" == cancelled
check "no fit queued for a cancelled scan" -- test "$(sql "SELECT count(*) FROM jobs WHERE kind = 'fit' AND scan_id = $S3")" == 0
check "cancelled queued scan never ran" -- test "$(points_stored "$S4")" == 0
req POST "/api/jobs/$J1/cancel"
expect_error 409 "" "cancel a finished job"
req POST "/api/scans/$S3/fits" '{}'
expect_error 409 "" "fit a scan that is not done"

# ---- a long fit (a large uploaded scan): cancel while running, and SIGTERM while running ----
python3 -c "
import json, math
n = 8000  # ~2.5 s for r = 1..8 on the test machine
x = [0.3 + 5.4 * ((i * 0.618034) % 1) for i in range(n)]
y = [0.3 + 5.4 * ((i * 0.414214) % 1) for i in range(n)]
s = [100 + 5000 * math.exp(-((a - 3) ** 2 + (b - 3) ** 2) / 8) for a, b in zip(x, y)]
print(json.dumps({'scan': {'pitch_um': 6, 'spot_radius_um': 1.342, 'bias_dn': 100,
                           'gain_e_per_dn': 3.153, 'read_noise_e': 5.67, 'frames': 12,
                           'x_um': x, 'y_um': y, 'signal_dn': s}}))" >"$T/long.json"
FITS0=$(sql "SELECT count(*) FROM fits")
req POST /api/fits "@$T/long.json"
JL=$(js "d['job']['id']")
check "long fit running" -- wait_job "$JL" running 10
req POST "/api/jobs/$JL/cancel"
expect_status 200 "cancel a running fit"
req POST /api/fits "@$T/long.json"
JT=$(js "d['job']['id']")
check "second long fit running" -- wait_job "$JT" running 10
start_s=$(date +%s)
stop_term
ok $? "SIGTERM during a fit: exit status 0"
check "the stop did not wait for the whole fit" -- test $(($(date +%s) - start_s)) -le 5
check "the fit given back: queued, claim not counted" -- \
    test "$(sql "SELECT state, attempts FROM jobs WHERE id = $JT")" == "queued|0"
check "the cancelled fit stored nothing" -- \
    test "$(sql "SELECT state, fit_id IS NULL FROM jobs WHERE id = $JL")" == "cancelled|1"
check "no fit stored meanwhile" -- test "$(sql "SELECT count(*) FROM fits")" == "$FITS0"
start
check "the fit given back runs again to done" -- wait_job "$JT" done 120
check "one fit stored" -- test "$(sql "SELECT count(*) FROM fits")" == $((FITS0 + 1))

stop_term
ok $? "SIGTERM: exit status 0"
finish
