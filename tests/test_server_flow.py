#!/usr/bin/env python3
"""test_server_flow.py IPSD IPS: the full path through a real ipsd (simulated bench) with a real
HTTP client: create a sensor, submit a small simulated scan, look at it held mid-raster (the
scan.point failpoint: what is stored and served while a scan runs), follow it to done (and over
the event stream), get the automatic fit, read the calibration back as JSON and CSV, and check the
map against `ips fit` run on the pixel raster downloaded from the API (the independent path: the
command-line tool over the scan-file contract) and against the database read by Python's sqlite3
module. Then a fit of another pixel with other options, a fit of an uploaded scan file that
supersedes the first calibration (history), the search, and a graceful stop."""
import csv
import io
import json
import math
import os
import struct
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, EventStream, Ipsd, wait_for

HOLD_AT = 480  # the raster point (1-based hit of scan.point) the scan is held at


def ips_fit(ips, scan_path, out_path, *opts):
    """`ips fit SCAN OPTS...` into out_path; its exit status."""
    with open(out_path, "wb") as out:
        return subprocess.run([ips, "fit", scan_path, *opts], stdout=out).returncode


def compare_with_ips(scan, ips, cal, fit, csv_text, db):
    """The stored calibration (JSON, CSV, database) and fit document against `ips fit`'s output on
    the downloaded raster. Returns the list of differences."""
    # the calibration is the kriged map (fit/krige.h), the one `ips fit` prints as kriged_map;
    # I0 and the status are the recommended r's fit's (fit/recommend.h)
    rec = ips["recommended_r"]
    best = [f for f in ips["fits"] if f["r"] == rec][0]
    km = ips["kriged_map"]
    g = km["grid"]
    fails = []

    def near(a, b, what):
        if len(a) != len(b) or any(abs(x - y) > 1e-9 for x, y in zip(a, b)):
            fails.append(what)
    if cal["r"] != g or cal.get("map") != "kriged":
        fails.append("calibration r %d map %s != ips fit's kriged map on %d x %d"
                     % (cal["r"], cal.get("map"), g, g))
    near(cal["S"], km["S"], "S vs ips fit")
    near(cal["S_err"], km["S_err"], "S_err vs ips fit")
    if abs(cal["I0"] - best["I0"]) > 1e-9 * abs(best["I0"]):
        fails.append("I0")
    if cal["status"] != best["status"] or cal["scan_id"] != scan:
        fails.append("status/provenance")
    if fit["best_r"] != ips["best_r"]:
        fails.append("fit best_r")
    if fit["result"].get("stored_map") != {"map": "kriged", "r": g}:
        fails.append("result.stored_map %r" % fit["result"].get("stored_map"))
    # the stored document follows the `ips fit` schema: the same fits, key for key (timing aside)
    def strip(f):
        return {k: v for k, v in f.items() if k != "timing_ms"}
    if [strip(f) for f in fit["result"]["fits"]] != [strip(f) for f in ips["fits"]]:
        fails.append("stored fits[] differ from ips fit's")
    for k in ("N", "n_points", "sigma", "method", "nonneg", "design_tol", "full_scale_dn",
              "best_r", "recommended_r", "recommended_reason", "range_edge"):
        if fit["result"][k] != ips[k]:
            fails.append("result." + k)
    if abs(fit["result"]["ftest"]["F"] - ips["ftest"]["F"]) > 1e-9 * ips["ftest"]["F"]:
        fails.append("F")
    near(fit["result"]["wiener"]["S"], ips["wiener"]["S"], "Wiener S")
    # CSV: one line per cell, row-major j*g + i
    rows = list(csv.DictReader(io.StringIO(csv_text)))
    if len(rows) != g * g:
        fails.append("CSV lines")
    near([float(r["S"]) for r in rows], [km["S"][int(r["j"]) * g + int(r["i"])] for r in rows],
         "CSV S")
    # S_res, the last column (an addition): none for the kriged map, whose S_err is its whole error
    if rows and list(rows[0].keys())[-1] != "S_res":
        fails.append("CSV: S_res is not the last column")
    elif any(r["S_res"] != "" for r in rows):
        fails.append("CSV S_res on the kriged map")
    # the database, read by Python's sqlite3 (little-endian float64 BLOBs, docs/schema.md)
    r, s = db.one("SELECT r, s FROM calibrations WHERE pixel_col = 50 AND pixel_row = 60 "
                  "AND superseded_by IS NULL")
    near(struct.unpack("<%dd" % (r * r), s), km["S"], "database S")
    return fails


def test(c, t, argv, daemons):
    ipsd_exe, ips = argv[1], argv[2]
    d = Ipsd(ipsd_exe, t)
    daemons.append(d)
    d.start(failpoints="scan.point=hold@%d" % HOLD_AT)
    db = Db(d.db)
    sse = EventStream(d.port)
    c.ok(sse.ready, "event stream subscribed")

    r = d.post("/api/sensors", {"model": "IMX-T", "serial": "flow-1", "n_cols": 128,
                                "n_rows": 96})
    c.status(r, 201, "create sensor")
    sensor = r.json()["id"]
    r = d.get("/api/sensors/%d" % sensor)
    c.eq((r.json()["n_cols"], r.json()["pitch_um"], r.json()["serial"]), (128, 6.0, "flow-1"),
         "sensor read back")

    # 3 x 3 pixels in 0.6 um steps: 31 x 31 points, 9 x 9 of them inside the POI (enough for r = 8)
    scan_req = {"sensor_id": sensor, "poi": {"col": 50, "row": 60},
                "raster": {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}, "seed": 7}
    r = d.post("/api/scans", scan_req)
    c.status(r, 202, "submit scan")
    scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.eq(r.json()["scan"]["raster"]["points_total"], 961, "scan answer: 961 points planned")
    # the job row was committed before the answer
    c.eq(db.val("SELECT count(*) FROM jobs WHERE id = ?", job), 1, "job row exists at once")

    # held after its 480th point: what a running scan shows
    c.ok(d.wait_held("scan.point", job), "scan held at point %d" % HOLD_AT)
    r = d.get("/api/scans/%d" % scan)
    c.eq((r.json()["state"], r.json()["points_done"]), ("running", HOLD_AT),
         "running scan: points_done while held")
    c.eq(db.one("SELECT count(*), min(point_index), max(point_index) FROM frames "
                "WHERE scan_id = ?", scan), (HOLD_AT, 0, HOLD_AT - 1),
         "points 0..479 stored while held")
    c.status(d.get("/api/scans/%d/points/%d" % (scan, HOLD_AT - 1)), 200, "last stored point")
    c.error(d.get("/api/scans/%d/points/%d" % (scan, HOLD_AT)), 404, "index",
            "the next point is not stored yet")
    c.error(d.post("/api/scans/%d/fits" % scan, {}), 409, "", "fit a running scan")
    c.eq(d.job_state(job), "running", "scan job running while held")
    d.release("scan.point", job)

    c.ok(d.wait_job(job, "done"), "scan job done")
    r = d.get("/api/scans/%d" % scan).json()
    c.eq((r["state"], r["points_done"], r["job_id"]), ("done", 961, job), "scan done, every point")
    c.eq(r["setup"]["pitch_um"], 6.0, "setup stored")
    c.eq(db.val("SELECT count(*) FROM frames WHERE scan_id = ?", scan), 961, "961 frame rows")

    # the automatic fit of the POI
    r = d.get("/api/jobs?kind=fit&scan=%d" % scan).json()
    c.eq(r["total"], 1, "one automatic fit job")
    fitjob = r["items"][0]["id"]
    j = d.wait_job(fitjob, "done")
    c.ok(j, "automatic fit done")
    fit_id = j["fit_id"]
    p = j["params"]
    c.eq((p["ftest"], p["ftest_r"], p["wiener"], p["r_max"]), ("top,left,bottom", 7, True, 8),
         "fit job params: paper's F-test, Wiener")

    # the pixel raster as a scan file, fitted by ips fit with the same options: every point of
    # the raster (the fit takes those inside the pixel, the Wiener baseline the whole raster)
    r = d.get("/api/scans/%d/pixels/0/0?all=1" % scan)
    c.status(r, 200, "pixel raster")
    pixel_path = os.path.join(t, "pixel.json")
    with open(pixel_path, "wb") as f:
        f.write(r.body)
    pixel = r.json()
    eps = 1e-6 * pixel["pitch_um"]
    def inside(v):
        return eps < v < pixel["pitch_um"] - eps
    c.eq(sum(inside(x) and inside(y) for x, y in zip(pixel["x_um"], pixel["y_um"])), 81,
         "pixel raster: 81 points inside")
    c.eq(ips_fit(ips, pixel_path, os.path.join(t, "ips.json"), "--ftest", "top,left,bottom",
                 "--wiener"), 0, "ips fit on the downloaded raster")
    # sigma_dn: eq. 5 of the paper as printed (what the automatic fit weights a point by),
    # computed here from the sensor's gain, read noise and bias (GET /api/sensors/ID), the setup's
    # analogue gain and the request's frames: sqrt(max(I - B, 0) + (R / G)^2) / sqrt(frames)
    sn = d.get("/api/sensors/%d" % sensor).json()
    gain = sn["gain_e_per_dn"] / d.get("/api/scans/%d" % scan).json()["setup"]["gain"]
    rg = sn["read_noise_e"] / gain
    want = [math.sqrt((max(v - sn["bias_dn"], 0.0) + rg * rg) / scan_req["raster"]["frames"])
            for v in pixel["signal_dn"]]
    got = pixel.get("sigma_dn") or []
    c.ok(pixel.get("sigma_model") == "paper" and len(got) == len(want) == 961 and
         all(abs(a - b) <= 1e-12 * b for a, b in zip(got, want)),
         "pixel raster: sigma_dn is eq. 5 with the sensor's gain and read noise (961 points)")
    c.ok(min(want) > rg / math.sqrt(2) and max(got) > 2 * min(got),
         "pixel raster: sigma_dn above the read-noise floor, larger where the signal is")

    calib_path = "/api/sensors/%d/pixels/50/60/calibration" % sensor
    r = d.get(calib_path)
    c.status(r, 200, "calibration JSON")
    cal = r.json()
    csv1 = d.get(calib_path + "?format=csv").text
    csv2 = d.get(calib_path, headers={"Accept": "text/csv"}).text
    c.ok(csv1 == csv2, "Accept: text/csv gives the same CSV")
    fit = d.get("/api/fits/%d" % fit_id).json()
    with open(os.path.join(t, "ips.json")) as f:
        ipsout = json.load(f)
    fails = compare_with_ips(scan, ipsout, cal, fit, csv1, db)
    for f in fails:
        print("FAIL:", f, file=sys.stderr)
    c.ok(not fails, "stored calibration = ips fit on the downloaded raster (JSON, CSV, database)")

    # the event stream saw the scan run (progress, ETA) and both jobs finish (the fit job's done
    # event is published just after the row is written: waited for, with the heartbeat)
    wait_for(lambda: any(e["id"] == fitjob and e["state"] == "done" for e in sse.events())
             and sse.has(": heartbeat"))
    ev = sse.events()
    run = [e for e in ev if e["id"] == job and e["state"] == "running" and e["phase"] == "raster"]
    good = (len(run) > 10 and all(e["points_total"] == 961 for e in run)
            and any(e["eta_s"] is not None and e["points_done"] > 0 for e in run)
            and any(e["id"] == job and e["state"] == "done" for e in ev)
            and any(e["id"] == fitjob and e["state"] == "done" for e in ev)
            and sorted(e["points_done"] for e in run) == [e["points_done"] for e in run])
    if not good:
        print("events:", ev[:3], len(ev), file=sys.stderr)
    c.ok(good, "SSE: running progress with ETA, then done, for the scan and its fit")
    c.ok(sse.has(": heartbeat"), "SSE heartbeat comment")
    # the raster's start (0 points), then one event per stored point, in order, none twice
    c.eq([e["points_done"] for e in run if e["points_done"] <= HOLD_AT],
         list(range(0, HOLD_AT + 1)), "SSE: one event per stored point up to the hold")
    sse.close()
    # ?job=ID: the job's current state first, then only its events
    one = EventStream(d.port, "/api/events?job=%d" % job)
    wait_for(lambda: one.events())
    e = one.events()[0] if one.events() else {}
    c.eq((e.get("id"), e.get("state"), e.get("points_done"), e.get("points_total")),
         (job, "done", 961, 961), "SSE ?job: its current state first")
    c.ok(one.has("retry: 3000"), "SSE retry hint")
    one.close()

    # a fit of another pixel with other options, asked to become that pixel's calibration (a
    # re-fit is only stored as a fit unless promoted: tests/test_server_promote.py)
    r = d.post("/api/scans/%d/fits" % scan, {"dcol": 1, "drow": 0, "r_min": 1, "r_max": 4,
                                              "sigma": "shot+read", "promote": True})
    c.status(r, 202, "fit another pixel")
    j2 = r.json()["job"]["id"]
    c.ok(d.wait_job(j2, "done"), "second fit done")
    p10 = os.path.join(t, "pixel10.json")
    with open(p10, "wb") as f:
        f.write(d.get("/api/scans/%d/pixels/1/0" % scan).body)
    ips_fit(ips, p10, os.path.join(t, "ips10.json"), "--r-min", "1", "--r-max", "4", "--sigma",
            "shot+read")
    cal10 = d.get("/api/sensors/%d/pixels/51/60/calibration" % sensor).json()
    with open(os.path.join(t, "ips10.json")) as f:
        ips10 = json.load(f)
    km = ips10["kriged_map"]  # without "map", a re-fit stores the kriged map too
    c.ok(cal10["r"] == km["grid"] and cal10["map"] == "kriged" and
         cal10["noise_model"] == "shot+read" and len(cal10["S"]) == len(km["S"]) and
         max(abs(a - b) for a, b in zip(cal10["S"], km["S"])) < 1e-9,
         "pixel (+1, 0) fitted with shot+read, r <= 4, = ips fit's kriged map")

    # an uploaded scan file (the same pixel's data) becomes the new calibration of (50, 60)
    upload = {"scan": pixel, "sensor_id": sensor, "pixel": {"col": 50, "row": 60},
              "optics": {"wavelength_nm": 550, "na": 0.25}, "ftest": "top,left,bottom",
              "wiener": True}
    r = d.post("/api/fits", upload)
    c.status(r, 202, "upload fit")
    j3 = d.wait_job(r.json()["job"]["id"], "done")
    c.ok(j3, "upload fit done")
    f3 = j3["fit_id"] if j3 else 0
    c.eq(d.get("/api/fits/%d" % f3).json()["scan_id"], None, "upload fit has no scan")
    h = d.get("/api/sensors/%d/pixels/50/60/history" % sensor).json()
    it = h["items"]
    c.eq((len(it), it[0]["current"], it[1]["superseded_by"] == it[0]["id"],
          it[0]["S"] == it[1]["S"]), (2, True, True, True),
         "history: two maps, newest first, the old one superseded")
    rr = it[0]["r"]
    hcsv = d.get("/api/sensors/%d/pixels/50/60/history?format=csv" % sensor).body
    c.eq(hcsv.count(b"\n"), 2 * rr * rr + 1, "history CSV lines")
    c.eq(d.get("/api/calibrations?sensor=%d&current=1" % sensor).json()["total"], 2,
         "search: two current maps")
    c.eq(d.get("/api/calibrations?sensor=%d" % sensor).json()["total"], 3,
         "search: three maps in all")
    r = d.get("/api/scans?sensor=%d&state=done" % sensor).json()
    c.eq((r["total"], r["items"][0]["id"]), (1, scan), "scan list filter")
    r = d.get("/api/scans/%d/points/480" % scan).json()
    c.eq((len(r["raw"]), len(r["raw"][0]), len(r["mean"])), (2, 9, 9),
         "a point's frames: 2 raw 3x3 frames")

    db.close()
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")
    log = d.log_text()
    c.ok("ipsd: stopped" in log, "graceful stop logged")
    c.ok("failpoint scan.point: job %d released" % job in log, "the hold and its release logged")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
