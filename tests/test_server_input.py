#!/usr/bin/env python3
"""test_server_input.py IPSD: bad input to a real ipsd gets its 4xx with the error body of
docs/contracts.md naming the field, and nothing stored changes (every table's row count, read by
Python's sqlite3 module, is the same before and after); unknown ids and paths 404, wrong methods
405; the static files handler serves only regular files inside the web directory; the bearer
token guards writes and leaves reads open; the OpenAPI document and the health check answer; bad
command lines exit 2 and a missing camera 1."""
import copy
import json
import os
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd

# the valid requests the bad ones are edited from
UPLOAD = {"pitch_um": 6, "spot_radius_um": 1.342, "bias_dn": 100, "gain_e_per_dn": 3.153,
          "read_noise_e": 5.67, "frames": 12, "x_um": [1, 2, 3], "y_um": [1, 2, 3],
          "signal_dn": [500, 600, 700]}


def edited(base, name, edit, **names):
    """A deep copy of base, bound to name, changed by the Python statement edit (names: more
    variables the statement may use)."""
    v = {name: copy.deepcopy(base), **names}
    exec(edit, {}, v)
    return v[name]


def test(c, t, argv, daemons):
    exe = argv[1]
    d = Ipsd(exe, t)
    daemons.append(d)
    # a web directory with a page, a sub-directory, and a symlink pointing outside it
    web = os.path.join(t, "web")
    os.makedirs(os.path.join(web, "sub"))
    os.makedirs(os.path.join(t, "outside"))
    with open(os.path.join(web, "index.html"), "w") as f:
        f.write("<h1>ipsd</h1>\n")
    with open(os.path.join(web, "sub", "style.css"), "w") as f:
        f.write("body{}\n")
    with open(os.path.join(t, "outside", "secret.txt"), "w") as f:
        f.write("TOPSECRET-CONTENT\n")
    os.symlink(os.path.join(t, "outside", "secret.txt"), os.path.join(web, "link.txt"))

    # the scan is held at its first point: it is cancelled before anything but that is stored
    d.start("--web", web, "--max-body", "2048", failpoints="scan.point=hold@1")
    db = Db(d.db)

    def counts():
        return db.one("SELECT (SELECT count(*) FROM sensors), (SELECT count(*) FROM scans), "
                      "(SELECT count(*) FROM jobs), (SELECT count(*) FROM frames), "
                      "(SELECT count(*) FROM fits), (SELECT count(*) FROM calibrations)")

    # one sensor, and one scan cancelled at its first point (not done), to aim requests at
    r = d.post("/api/sensors", {"model": "IMX-I", "serial": "input-1"})
    c.status(r, 201, "create sensor")
    sensor = r.json()["id"]
    scan_ok = {"sensor_id": sensor, "poi": {"col": 100, "row": 100},
               "raster": {"area_px": 5, "step_um": 0.6, "sub_px": 3, "frames": 1}}
    r = d.post("/api/scans", scan_ok)
    c.status(r, 202, "create scan")
    scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_held("scan.point", job), "scan held at its first point")
    c.status(d.post("/api/scans/%d/cancel" % scan), 200, "cancel it")
    c.ok(d.wait_hold_ended("scan.point", job), "the cancel ended the hold")
    c.ok(d.wait_job(job, "cancelled"), "scan job cancelled")
    before = counts()
    c.eq(before, (1, 1, 1, 1, 0, 0), "one sensor, scan, job and point stored")

    # ---- sensors ----
    c.error(d.post("/api/sensors", '{"model": "IMX", '), 400, "", "malformed JSON")
    c.error(d.post("/api/sensors", "[1, 2]"), 400, "", "not an object")
    c.error(d.post("/api/sensors", {"model": 5, "serial": "x"}), 400, "model",
            "model of the wrong type")
    c.error(d.post("/api/sensors", {"model": "IMX"}), 422, "serial", "serial missing")
    c.error(d.post("/api/sensors", {"model": "IMX", "serial": "2", "n_cols": 0}), 422, "n_cols",
            "n_cols = 0")
    c.error(d.post("/api/sensors", {"model": "IMX", "serial": "2", "pitch_um": -6}), 422,
            "pitch_um", "negative pitch")
    c.error(d.post("/api/sensors", {"model": "IMX", "serial": "2", "bias_dn": 20000}), 422,
            "bias_dn", "bias above full scale")
    c.error(d.post("/api/sensors", {"model": "IMX", "serial": "2", "colour": "red"}), 422,
            "colour", "unknown field")
    c.error(d.post("/api/sensors", {"model": "IMX-I", "serial": "input-1"}), 409, "serial",
            "duplicate sensor")
    c.error(d.post("/api/sensors", '{"model": "IMX", "serial": "1", "model": "X"}'), 400, "",
            "duplicate key")
    c.error(d.post("/api/sensors", {"model": "IMX", "serial": "2"},
                   headers={"Content-Type": "text/plain"}), 415, "", "text/plain body")
    c.error(d.post("/api/sensors", {"model": "a", "serial": "b"}, headers={"Content-Type": None}),
            415, "", "no content type")
    big = '{"model": "IMX", "serial": "big"' + " " * 4000 + "}\n"
    c.error(d.post("/api/sensors", big), 413, "", "oversized body (Content-Length)")
    c.error(d.req("POST", "/api/sensors", big, chunked=True), 413, "", "oversized chunked body")

    # ---- scans ----
    def bad_scan(edit, status, field):
        c.error(d.post("/api/scans", edited(scan_ok, "s", edit)), status, field,
                "scan with " + edit)
    bad_scan("s['raster']['step_um'] = -0.6", 422, "raster.step_um")
    bad_scan("s['raster']['step_um'] = 0", 422, "raster.step_um")
    bad_scan("s['raster']['step_um'] = 0.7", 422, "raster.step_um")
    bad_scan("s['raster']['step_um'] = '0.6'", 400, "raster.step_um")
    bad_scan("s['raster']['frames'] = 0", 422, "raster.frames")
    bad_scan("s['raster']['area_px'] = 4", 422, "raster.area_px")
    bad_scan("s['raster']['sub_px'] = 1", 422, "raster.sub_px")
    bad_scan("s['raster']['speed'] = 1", 422, "raster.speed")
    bad_scan("s['poi']['col'] = 256", 422, "poi.col")
    bad_scan("s['poi']['row'] = 0", 422, "poi.row")
    bad_scan("s['poi']['col'] = -1", 422, "poi.col")
    bad_scan("s['poi']['col'] = 1.5", 400, "poi.col")
    bad_scan("del s['poi']", 422, "poi")
    bad_scan("s['sensor_id'] = 999", 422, "sensor_id")
    bad_scan("s['sensor_id'] = '1'", 400, "sensor_id")
    bad_scan("del s['sensor_id']", 422, "sensor_id")
    bad_scan("s['optics'] = {'na': 2}", 422, "optics.na")
    bad_scan("s['optics'] = {'na': 0.25, 'spot_radius_um': 1.3}", 422, "optics.spot_radius_um")
    bad_scan("s['optics'] = 'wide'", 400, "optics")
    bad_scan("s['scene'] = 'moon'", 422, "scene")
    bad_scan("s['seed'] = -1", 422, "seed")

    # ---- fits ----
    c.error(d.post("/api/scans/999/fits", {}), 404, "", "fit of an unknown scan")

    def bad_fit(body, status, field):
        c.error(d.post("/api/scans/%d/fits" % scan, body), status, field, "fit " + body)
    bad_fit('{"r_min": 0}', 422, "r_min")
    bad_fit('{"r_min": 5, "r_max": 3}', 422, "r_min")
    bad_fit('{"r_max": 33}', 422, "r_max")
    bad_fit('{"sigma": "gauss"}', 422, "sigma")
    bad_fit('{"ftest": "up"}', 422, "ftest")
    bad_fit('{"ftest": 5}', 400, "ftest")
    bad_fit('{"wiener": "yes"}', 400, "wiener")
    bad_fit('{"dcol": 2}', 422, "dcol")
    bad_fit('{"method": "newton"}', 422, "method")
    bad_fit("{}", 409, "")

    def bad_upload(edit, status, field):
        body = edited({"scan": UPLOAD}, "b", edit, SENSOR=sensor)
        c.error(d.post("/api/fits", body), status, field, "upload with " + edit)
    bad_upload("del b['scan']", 422, "scan")
    bad_upload("b['scan'] = [1]", 400, "scan")
    bad_upload("del b['scan']['x_um']", 422, "scan.x_um")
    bad_upload("b['scan']['pitch_um'] = -6", 422, "scan.pitch_um")
    bad_upload("b['scan']['y_um'] = [1, 2]", 422, "scan.y_um")
    bad_upload("b['scan']['x_um'] = []; b['scan']['y_um'] = []; b['scan']['signal_dn'] = []", 422,
               "scan.x_um")
    bad_upload("b['sensor_id'] = SENSOR", 422, "pixel")
    bad_upload("b['sensor_id'] = 999; b['pixel'] = {'col': 1, 'row': 1}", 422, "sensor_id")
    bad_upload("b['sensor_id'] = SENSOR; b['pixel'] = {'col': 300, 'row': 1}", 422, "pixel.col")
    bad_upload("b['scan']['pitch_um'] = 5; b['sensor_id'] = SENSOR; "
               "b['pixel'] = {'col': 1, 'row': 1}", 422, "scan.pitch_um")
    bad_upload("b['dcol'] = 1", 422, "dcol")

    # ---- unknown ids, paths, methods, queries ----
    for p in ["/api/sensors/999", "/api/scans/999", "/api/jobs/999", "/api/fits/999",
              "/api/calibrations/999", "/api/scans/abc", "/api/sensors/0", "/api/nope", "/api",
              "/api/sensors/%d/pixels/5/5/calibration" % sensor,
              "/api/sensors/%d/pixels/5/5/history" % sensor,
              "/api/sensors/%d/pixels/500/5/calibration" % sensor,
              "/api/sensors/999/pixels/5/5/calibration", "/api/scans/%d/points/2600" % scan,
              "/api/scans/%d/points/2601" % scan, "/api/scans/%d/points/-1" % scan,
              "/api/scans/%d/pixels/2/0" % scan, "/api/scans/999/pixels/0/0"]:
        r = d.get(p)
        c.status(r, 404, "GET " + p)
        try:
            code = r.json()["error"]["code"]
        except (ValueError, KeyError, TypeError):
            code = None
        c.eq(code, "not_found", "GET %s: error body" % p)
    c.error(d.post("/api/jobs/999/cancel"), 404, "", "cancel an unknown job")
    c.error(d.req("DELETE", "/api/sensors"), 405, "", "DELETE /api/sensors")
    c.error(d.req("PUT", "/api/scans/%d" % scan), 405, "", "PUT a scan")
    c.error(d.get("/api/scans?limit=0"), 422, "limit", "limit 0")
    c.error(d.get("/api/scans?limit=ten"), 400, "limit", "limit ten")
    c.error(d.get("/api/jobs?state=sleeping"), 422, "state", "unknown state")
    c.error(d.get("/api/jobs?kind=dance"), 422, "kind", "unknown kind")
    c.error(d.get("/api/calibrations?format=xml"), 400, "format", "unknown format")
    c.error(d.get("/api/events?job=x"), 400, "job", "events of job x")

    after = counts()
    c.eq(after, before, "bad input changed nothing stored")

    # ---- static files ----
    r = d.get("/")
    c.eq((r.status, r.text.rstrip("\n")), (200, "<h1>ipsd</h1>"), "GET / serves index.html")
    r = d.req("HEAD", "/web/index.html")
    c.ok((r.headers.get("Content-Type") or "").lower().startswith("text/html"),
         "index.html is text/html (%r)" % r.headers.get("Content-Type"))
    c.status(d.get("/web/sub/style.css"), 200, "a file in a sub-directory")
    # paths sent as they are (http.client does not normalise them)
    for p in ["/web/../outside/secret.txt", "/../outside/secret.txt",
              "/web/%2e%2e/outside/secret.txt", "/web/..%2Foutside%2Fsecret.txt", "/link.txt"]:
        r = d.get(p)
        c.ok(r.status in (403, 404) and b"TOPSECRET" not in r.body,
             "traversal %s refused (%d)" % (p, r.status))
    for p in ["/web/sub", "/web/missing.html", "/nothing"]:
        c.status(d.get(p), 404, "static " + p)
    c.status(d.post("/", {}), 405, "POST /")

    # ---- health and the OpenAPI document ----
    c.eq(d.get("/api/health").json()["status"], "ok", "health ok")
    r = d.get("/api/openapi.json").json()
    c.eq((r["openapi"], "/api/scans" in r["paths"]), ("3.1.0", True),
         "openapi 3.1 with the scan route")

    # ---- the token: writes need it, reads do not ----
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")
    token = os.path.join(t, "token")
    with open(token, "w") as f:
        f.write("  s3cret-token\n")
    d.start("--web", web, "--token", token)
    sensor_tok = {"model": "IMX-T", "serial": "tok"}
    c.error(d.post("/api/sensors", sensor_tok), 401, "", "write without the token")
    c.error(d.post("/api/sensors", sensor_tok, headers={"Authorization": "Bearer wrong"}), 401, "",
            "write with a wrong token")
    c.error(d.post("/api/jobs/1/cancel", headers={"Authorization": "Basic czNjcmV0LXRva2Vu"}),
            401, "", "cancel with another scheme")
    c.eq(counts(), after, "refused writes stored nothing")
    c.status(d.post("/api/sensors", sensor_tok,
                    headers={"Authorization": "Bearer s3cret-token"}), 201, "write with the token")
    r = d.get("/api/sensors")
    c.eq((r.status, r.json()["total"]), (200, 2), "reads stay open")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")
    db.close()

    # ---- bad command lines and a missing camera ----
    def run(*args):
        p = subprocess.run([exe, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                           text=True, timeout=ipsd_http.DEADLINE_S)
        return p.returncode, p.stderr
    rc, err = run("--workers", "0")
    c.eq(rc, 2, "--workers 0: exit 2")
    c.ok("workers" in err, "--workers 0 is named")
    rc, err = run("--token", os.path.join(t, "nothing"))
    c.eq(rc, 2, "missing token file: exit 2")
    rc, err = run("--listen", "127.0.0.1:0", "--db", os.path.join(t, "cam.db"), "--bench",
                  "libcamera")
    c.eq(rc, 1, "--bench libcamera without a camera: exit 1")
    c.ok("camera" in err.lower(), "--bench libcamera failure says why: " + err)
    # a malformed IPSD_FAILPOINTS is refused at start (exit 1), naming the term
    env = dict(os.environ, IPSD_FAILPOINTS="scan.pint=hold")
    p = subprocess.run([exe, "--listen", "127.0.0.1:0", "--db", os.path.join(t, "fp.db")],
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env,
                       timeout=ipsd_http.DEADLINE_S)
    c.eq(p.returncode, 1, "unknown failpoint: exit 1")
    c.ok("scan.pint" in p.stderr, "unknown failpoint named: " + p.stderr)


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
