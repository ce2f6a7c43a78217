#!/usr/bin/env python3
"""test_server_scanfile.py IPSD IPS: a stored scan downloaded as one scan file with its sub-frame
(GET /api/scans/{id}/scanfile) and fitted off line for every pixel (`ips fit FILE --pixels all`)
gives the maps the server's fit of every pixel stored.

A simulated paperlike scan (the paper's raster: 5 x 5 pixels of 6 um in 0.6 um steps, 7 x 7
sub-frame) is fitted on the server with "pixels": "all" and some options; then
- the file: the POI's x_um, y_um, signal_dn are those of GET .../pixels/0/0?all=1, subframe has
  sub_px 7, the scan's step and, for a pixel other than the POI, the column of means of GET
  .../pixels/{dcol}/{drow}?all=1, whose positions are the file's minus (dcol, drow) pitches (in
  Python's own IEEE arithmetic: the positions every pixel gets are the server's, bit for bit);
- `ips fit FILE --pixels all` with the same options covers the pixels GET .../coverage covers,
  with the same reasons for the others, and each fitted pixel's document equals the result the
  server stored for that pixel (GET /api/fits/{id} of the job's fit_ids): every member ips
  prints but the wall times, compared as the JSON numbers read back (17 digits: equal, no
  tolerance);
- 404 for an unknown scan."""
import json
import os
import subprocess
import sys

import ipsd_http
from fitdoc import untimed
from ipsd_http import Ipsd

SUB, AREA, STEP, PITCH = 7, 5, 0.6, 6.0
OPTS = {"r_max": 7, "wiener": True, "ftest": "top,left,bottom", "ftest_r": 7}
IPS_OPTS = ["--r-max", "7", "--wiener", "--ftest", "top,left,bottom", "--ftest-r", "7"]


def test(c, t, argv, daemons):
    ips = argv[2]
    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start()
    r = d.post("/api/sensors", {"model": "IMX-A", "serial": "file-1", "pitch_um": PITCH})
    c.status(r, 201, "create a sensor")
    sensor = r.json()["id"]
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 40, "row": 50},
                              "raster": {"area_px": AREA, "step_um": STEP, "sub_px": SUB,
                                         "frames": 2}, "scene": "paperlike", "seed": 11})
    c.status(r, 202, "submit a 5 x 5-pixel scan with a 7 x 7 sub-frame")
    scan, scan_job = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_job(scan_job, "done", timeout=600), "the scan is done")
    c.error(d.get("/api/scans/999/scanfile"), 404, "", "unknown scan: 404")

    r = d.post("/api/scans/%d/fits" % scan, dict(OPTS, pixels="all"))
    c.status(r, 202, "fit every pixel on the server")
    job = r.json()["job"]["id"]
    c.ok(d.wait_job(job, "done", timeout=600), "the fit of every pixel is done")

    r = d.get("/api/scans/%d/scanfile" % scan)
    c.status(r, 200, "download the scan file with its sub-frame")
    f = r.json()
    path = os.path.join(t, "scan.json")
    with open(path, "wb") as out:
        out.write(r.body)
    p0 = d.get("/api/scans/%d/pixels/0/0?all=1" % scan).json()
    c.ok(all(f[k] == p0[k] for k in ("x_um", "y_um", "signal_dn", "pitch_um", "bias_dn",
                                     "gain_e_per_dn", "read_noise_e", "frames",
                                     "spot_radius_um", "full_scale_dn")),
         "the POI's arrays and constants are those of pixels/0/0?all=1")
    sub = f.get("subframe") or {}
    c.eq((sub.get("sub_px"), sub.get("step_um"), len(sub.get("signal_dn", []))),
         (SUB, STEP, len(f["x_um"])), "subframe: sub_px, the scan's step, a frame per point")
    h = SUB // 2
    for dc, dr in ((2, -1), (-3, 3)):
        pp = d.get("/api/scans/%d/pixels/%d/%d?all=1" % (scan, dc, dr)).json()
        col = [fr[(dr + h) * SUB + dc + h] for fr in sub["signal_dn"]]
        c.eq(col, pp["signal_dn"], "pixel (%+d, %+d): the sub-frame's column is its response"
             % (dc, dr))
        c.ok(pp["x_um"] == [x - dc * PITCH for x in f["x_um"]] and
             pp["y_um"] == [y - dr * PITCH for y in f["y_um"]],
             "pixel (%+d, %+d): its positions are the file's minus whole pitches, bit for bit"
             % (dc, dr))

    proc = subprocess.run([ips, "fit", path, "--pixels", "all", *IPS_OPTS],
                          capture_output=True, text=True)
    c.eq(proc.returncode, 0, "ips fit --pixels all on the downloaded file: " + proc.stderr)
    doc = json.loads(proc.stdout)
    cov = d.get("/api/scans/%d/coverage" % scan).json()
    mine = {(e["dcol"], e["drow"]): e for e in doc["pixels"]}
    theirs = {(e["dcol"], e["drow"]): e for e in cov["pixels"]}
    c.eq({k: (e["status"] == "fitted", e["n_inside"], e["reason"]) for k, e in mine.items()},
         {k: (e["status"] == "covered", e["n_inside"], e["reason"]) for k, e in theirs.items()},
         "ips covers the pixels the server covers, with the same reasons for the others")
    ids = d.get("/api/jobs/%d" % job).json()["fit_ids"]
    c.eq(len(ids), 25, "the server stored 25 fits")
    same = 0
    for fid in ids:
        fit = d.get("/api/fits/%d" % fid).json()
        e = mine.get((fit["dcol"], fit["drow"]))
        if not e or e["status"] != "fitted":
            c.ok(False, "fit %d's pixel (%+d, %+d) is fitted by ips" % (fid, fit["dcol"],
                                                                       fit["drow"]))
            continue
        a, b = untimed(e["fit"]), untimed(fit["result"])
        diff = [k for k in a if a[k] != b.get(k)]
        c.ok(not diff, "pixel (%+d, %+d): ips's document is the server's stored result%s"
             % (fit["dcol"], fit["drow"], " (differs in %s)" % diff if diff else ""))
        same += not diff
    print("%d of 25 pixels equal, every member but the times" % same)


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
