#!/usr/bin/env bash
# test_server_input.sh IPSD: bad input to a real ipsd gets its 4xx with the error body of
# docs/contracts.md naming the field, and nothing stored changes (every table's row count, read by
# the sqlite3 shell, is the same before and after); unknown ids and paths 404, wrong methods 405;
# the static files handler serves only regular files inside the web directory; the bearer token
# guards writes and leaves reads open; the OpenAPI document and the health check answer.
source "$(dirname "$0")/test_server_lib.sh"
setup "$1"

# a web directory with a page, a sub-directory, and a symlink pointing outside it
mkdir -p "$T/web/sub" "$T/outside"
echo '<h1>ipsd</h1>' >"$T/web/index.html"
echo 'body{}' >"$T/web/sub/style.css"
echo 'TOPSECRET-CONTENT' >"$T/outside/secret.txt"
ln -s "$T/outside/secret.txt" "$T/web/link.txt"

start --web "$T/web" --max-body 2048
counts() {
    sql "SELECT (SELECT count(*) FROM sensors), (SELECT count(*) FROM scans),
                (SELECT count(*) FROM jobs), (SELECT count(*) FROM frames),
                (SELECT count(*) FROM fits), (SELECT count(*) FROM calibrations)"
}

# one sensor, and one scan cancelled at once (not done, few points if any), to aim requests at
req POST /api/sensors '{"model": "IMX-I", "serial": "input-1"}'
expect_status 201 "create sensor"
SENSOR=$(js "d['id']")
SCAN_OK='{"sensor_id": '$SENSOR', "poi": {"col": 100, "row": 100}, "raster": {"area_px": 5, "step_um": 0.6, "sub_px": 3, "frames": 1}}'
req POST /api/scans "$SCAN_OK"
expect_status 202 "create scan"
SCAN=$(js "d['scan']['id']")
req POST "/api/scans/$SCAN/cancel"
expect_status 200 "cancel it"
BEFORE=$(counts)

# ---- sensors ----
req POST /api/sensors '{"model": "IMX", '
expect_error 400 "" "malformed JSON"
req POST /api/sensors '[1, 2]'
expect_error 400 "" "not an object"
req POST /api/sensors '{"model": 5, "serial": "x"}'
expect_error 400 model "model of the wrong type"
req POST /api/sensors '{"model": "IMX"}'
expect_error 422 serial "serial missing"
req POST /api/sensors '{"model": "IMX", "serial": "2", "n_cols": 0}'
expect_error 422 n_cols "n_cols = 0"
req POST /api/sensors '{"model": "IMX", "serial": "2", "pitch_um": -6}'
expect_error 422 pitch_um "negative pitch"
req POST /api/sensors '{"model": "IMX", "serial": "2", "bias_dn": 20000}'
expect_error 422 bias_dn "bias above full scale"
req POST /api/sensors '{"model": "IMX", "serial": "2", "colour": "red"}'
expect_error 422 colour "unknown field"
req POST /api/sensors '{"model": "IMX-I", "serial": "input-1"}'
expect_error 409 serial "duplicate sensor"
req POST /api/sensors '{"model": "IMX", "serial": "1", "model": "X"}'
expect_error 400 "" "duplicate key"
req POST /api/sensors '{"model": "IMX", "serial": "2"}' -H 'Content-Type: text/plain'
expect_error 415 "" "text/plain body"
STATUS=$(curl -s -o "$T/body" -w '%{http_code}' -X POST --data-binary '{"model": "a", "serial": "b"}' \
         -H 'Content-Type:' "$BASE/api/sensors")
BODY=$(cat "$T/body")
expect_error 415 "" "no content type"
python3 -c "print('{\"model\": \"IMX\", \"serial\": \"big\"' + ' ' * 4000 + '}')" >"$T/big.json"
STATUS=$(curl -s -o "$T/body" -w '%{http_code}' -X POST -H 'Content-Type: application/json' \
         --data-binary @"$T/big.json" "$BASE/api/sensors")
BODY=$(cat "$T/body")
expect_error 413 "" "oversized body (Content-Length)"
STATUS=$(curl -s -o "$T/body" -w '%{http_code}' -X POST -H 'Content-Type: application/json' \
         -H 'Transfer-Encoding: chunked' --data-binary @"$T/big.json" "$BASE/api/sensors")
BODY=$(cat "$T/body")
expect_error 413 "" "oversized chunked body"

# ---- scans ----
scan_with() { # scan_with PYTHON-DICT-EDIT: the valid request changed by a Python statement on s
    python3 -c "import json; s = json.loads('''$SCAN_OK'''); $1; print(json.dumps(s))"
}
bad_scan() { # bad_scan EDIT STATUS FIELD
    req POST /api/scans "$(scan_with "$1")"
    expect_error "$2" "$3" "scan with $1"
}
bad_scan "s['raster']['step_um'] = -0.6" 422 raster.step_um
bad_scan "s['raster']['step_um'] = 0" 422 raster.step_um
bad_scan "s['raster']['step_um'] = 0.7" 422 raster.step_um
bad_scan "s['raster']['step_um'] = '0.6'" 400 raster.step_um
bad_scan "s['raster']['frames'] = 0" 422 raster.frames
bad_scan "s['raster']['area_px'] = 4" 422 raster.area_px
bad_scan "s['raster']['sub_px'] = 1" 422 raster.sub_px
bad_scan "s['raster']['speed'] = 1" 422 raster.speed
bad_scan "s['poi']['col'] = 256" 422 poi.col
bad_scan "s['poi']['row'] = 0" 422 poi.row
bad_scan "s['poi']['col'] = -1" 422 poi.col
bad_scan "s['poi']['col'] = 1.5" 400 poi.col
bad_scan "del s['poi']" 422 poi
bad_scan "s['sensor_id'] = 999" 422 sensor_id
bad_scan "s['sensor_id'] = '1'" 400 sensor_id
bad_scan "del s['sensor_id']" 422 sensor_id
bad_scan "s['optics'] = {'na': 2}" 422 optics.na
bad_scan "s['optics'] = {'na': 0.25, 'spot_radius_um': 1.3}" 422 optics.spot_radius_um
bad_scan "s['optics'] = 'wide'" 400 optics
bad_scan "s['scene'] = 'moon'" 422 scene
bad_scan "s['seed'] = -1" 422 seed

# ---- fits ----
req POST /api/scans/999/fits '{}'
expect_error 404 "" "fit of an unknown scan"
bad_fit() { # bad_fit BODY STATUS FIELD
    req POST "/api/scans/$SCAN/fits" "$1"
    expect_error "$2" "$3" "fit $1"
}
bad_fit '{"r_min": 0}' 422 r_min
bad_fit '{"r_min": 5, "r_max": 3}' 422 r_min
bad_fit '{"r_max": 33}' 422 r_max
bad_fit '{"sigma": "gauss"}' 422 sigma
bad_fit '{"ftest": "up"}' 422 ftest
bad_fit '{"ftest": 5}' 400 ftest
bad_fit '{"wiener": "yes"}' 400 wiener
bad_fit '{"dcol": 2}' 422 dcol
bad_fit '{"method": "newton"}' 422 method
bad_fit '{}' 409 ""
UPLOAD='{"pitch_um": 6, "spot_radius_um": 1.342, "bias_dn": 100, "gain_e_per_dn": 3.153,
         "read_noise_e": 5.67, "frames": 12, "x_um": [1, 2, 3], "y_um": [1, 2, 3], "signal_dn": [500, 600, 700]}'
bad_upload() { # bad_upload PYTHON-EDIT-OF-b STATUS FIELD
    local body
    body=$(python3 -c "import json; b = {'scan': json.loads('''$UPLOAD''')}; $1; print(json.dumps(b))")
    req POST /api/fits "$body"
    expect_error "$2" "$3" "upload with $1"
}
bad_upload "del b['scan']" 422 scan
bad_upload "b['scan'] = [1]" 400 scan
bad_upload "del b['scan']['x_um']" 422 scan.x_um
bad_upload "b['scan']['pitch_um'] = -6" 422 scan.pitch_um
bad_upload "b['scan']['y_um'] = [1, 2]" 422 scan.y_um
bad_upload "b['scan']['x_um'] = []; b['scan']['y_um'] = []; b['scan']['signal_dn'] = []" 422 scan.x_um
bad_upload "b['sensor_id'] = $SENSOR" 422 pixel
bad_upload "b['sensor_id'] = 999; b['pixel'] = {'col': 1, 'row': 1}" 422 sensor_id
bad_upload "b['sensor_id'] = $SENSOR; b['pixel'] = {'col': 300, 'row': 1}" 422 pixel.col
bad_upload "b['scan']['pitch_um'] = 5; b['sensor_id'] = $SENSOR; b['pixel'] = {'col': 1, 'row': 1}" 422 scan.pitch_um
bad_upload "b['dcol'] = 1" 422 dcol

# ---- unknown ids, paths, methods, queries ----
for p in /api/sensors/999 /api/scans/999 /api/jobs/999 /api/fits/999 /api/calibrations/999 \
         /api/scans/abc /api/sensors/0 /api/nope /api "/api/sensors/$SENSOR/pixels/5/5/calibration" \
         "/api/sensors/$SENSOR/pixels/5/5/history" "/api/sensors/$SENSOR/pixels/500/5/calibration" \
         "/api/sensors/999/pixels/5/5/calibration" "/api/scans/$SCAN/points/2600" \
         "/api/scans/$SCAN/points/2601" "/api/scans/$SCAN/points/-1" "/api/scans/$SCAN/pixels/2/0" /api/scans/999/pixels/0/0; do
    req GET "$p"
    expect_status 404 "GET $p"
    check "GET $p: error body" -- test "$(js "d['error']['code']")" == not_found
done
req POST /api/jobs/999/cancel
expect_error 404 "" "cancel an unknown job"
req DELETE /api/sensors
expect_error 405 "" "DELETE /api/sensors"
req PUT "/api/scans/$SCAN"
expect_error 405 "" "PUT a scan"
req GET '/api/scans?limit=0'
expect_error 422 limit "limit 0"
req GET '/api/scans?limit=ten'
expect_error 400 limit "limit ten"
req GET '/api/jobs?state=sleeping'
expect_error 422 state "unknown state"
req GET '/api/jobs?kind=dance'
expect_error 422 kind "unknown kind"
req GET '/api/calibrations?format=xml'
expect_error 400 format "unknown format"
req GET '/api/events?job=x'
expect_error 400 job "events of job x"

AFTER=$(counts)
check "bad input changed nothing stored ($BEFORE -> $AFTER)" -- test "$BEFORE" == "$AFTER"

# ---- static files ----
req GET /
check "GET / serves index.html" -- test "$STATUS|$BODY" == "200|<h1>ipsd</h1>"
check "index.html is text/html" -- bash -c "curl -sI '$BASE/web/index.html' | grep -qi '^content-type: text/html'"
req GET /web/sub/style.css
expect_status 200 "a file in a sub-directory"
for p in /web/../outside/secret.txt /../outside/secret.txt /web/%2e%2e/outside/secret.txt \
         /web/..%2Foutside%2Fsecret.txt /link.txt; do
    STATUS=$(curl -s --path-as-is -o "$T/body" -w '%{http_code}' "$BASE$p")
    [[ $STATUS == 403 || $STATUS == 404 ]] && ! grep -q TOPSECRET "$T/body"
    ok $? "traversal $p refused ($STATUS)"
done
for p in /web/sub /web/missing.html /nothing; do
    req GET "$p"
    expect_status 404 "static $p"
done
req POST / '{}'
expect_status 405 "POST /"

# ---- health and the OpenAPI document ----
req GET /api/health
check "health ok" -- test "$(js "d['status']")" == ok
req GET /api/openapi.json
check "openapi 3.1 with the scan route" -- test "$(js "d['openapi'], '/api/scans' in d['paths']")" == "('3.1.0', True)"

# ---- the token: writes need it, reads do not ----
stop_term
printf '  s3cret-token\n' >"$T/token"
start --web "$T/web" --token "$T/token"
req POST /api/sensors '{"model": "IMX-T", "serial": "tok"}'
expect_error 401 "" "write without the token"
req POST /api/sensors '{"model": "IMX-T", "serial": "tok"}' -H 'Authorization: Bearer wrong'
expect_error 401 "" "write with a wrong token"
req POST "/api/jobs/1/cancel" '' -H 'Authorization: Basic czNjcmV0LXRva2Vu'
expect_error 401 "" "cancel with another scheme"
check "refused writes stored nothing" -- test "$(counts)" == "$AFTER"
req POST /api/sensors '{"model": "IMX-T", "serial": "tok"}' -H 'Authorization: Bearer s3cret-token'
expect_status 201 "write with the token"
req GET /api/sensors
check "reads stay open" -- test "$STATUS|$(js "d['total']")" == "200|2"
stop_term
ok $? "SIGTERM: exit status 0"

# ---- bad command lines and a missing camera ----
"$IPSD" --workers 0 2>"$T/err"
check "--workers 0: exit 2" -- test $? == 2
grep -q "workers" "$T/err"
ok $? "--workers 0 is named"
"$IPSD" --token "$T/nothing" 2>"$T/err"
check "missing token file: exit 2" -- test $? == 2
"$IPSD" --listen 127.0.0.1:0 --db "$T/cam.db" --bench libcamera 2>"$T/err"
check "--bench libcamera without a camera: exit 1" -- test $? == 1
grep -qi "camera\|libcamera" "$T/err"
ok $? "--bench libcamera failure says why: $(cat "$T/err")"
finish
