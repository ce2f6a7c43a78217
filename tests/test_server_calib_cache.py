#!/usr/bin/env python3
"""test_server_calib_cache.py IPSD IPS: the cache of current-calibration replies
(api/api_calib_cache.h) never serves a stale map. Through a real ipsd, its SQLite file read by
Python's sqlite3 module as the independent judge of which calibration is current:

- the second read of a pixel's calibration is a cache hit (GET /api/health's calibration_cache
  counters) with the same bytes as the first and as the uncached GET /api/calibrations/{id};
- after every change of the pixel's calibration (an upload with a target pixel, a promote), the
  very next read shows the calibration the database says is current;
- a pixel without a calibration answers 404 (never cached), then its first calibration;
- CSV replies are not cached and agree with the JSON."""
import json
import os
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd

POI = (20, 30)


def current_in_db(db, sensor, col, row):
    return db.val("SELECT id FROM calibrations WHERE sensor_id = ? AND pixel_col = ? AND "
                  "pixel_row = ? AND superseded_by IS NULL", sensor, col, row)


def test(c, t, argv, daemons):
    ips = argv[2]
    path = os.path.join(t, "pixel.json")
    subprocess.run([ips, "simulate", "--scene", "paperlike", "--seed", "7", "-o", path],
                   check=True, stdout=subprocess.DEVNULL)
    with open(path) as f:
        scan_file = json.load(f)

    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start()
    db = Db(d.db)
    sensor = d.post("/api/sensors", {"model": "IMX-C", "serial": "cache-1", "n_cols": 64,
                                     "n_rows": 48}).json()["id"]
    pix = "/api/sensors/%d/pixels/%d/%d/calibration" % (sensor, POI[0], POI[1])

    def upload(r_max):
        r = d.post("/api/fits", {"scan": scan_file, "sensor_id": sensor,
                                 "pixel": {"col": POI[0], "row": POI[1]}, "r_max": r_max})
        c.status(r, 202, "upload with a target pixel, r_max %d" % r_max)
        return d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None

    def counters():
        h = d.get("/api/health").json()["calibration_cache"]
        return h["hits"], h["misses"]

    # ---- no calibration: 404, twice (a miss is not remembered as an answer) ----
    c.error(d.get(pix), 404, "", "no calibration yet")
    c.error(d.get(pix), 404, "", "still none")

    # ---- first calibration: a miss, then a hit with the same bytes ----
    j = upload(2)
    c.ok(j, "first upload fitted")
    h0 = counters()
    a, b = d.get(pix), d.get(pix)
    c.status(a, 200, "first read")
    h1 = counters()
    c.eq((h1[0] - h0[0], h1[1] - h0[1]), (1, 1), "the first read misses, the second hits")
    c.eq(b.body, a.body, "the hit has the bytes of the miss")
    cal = a.json()
    c.eq(cal["id"], current_in_db(db, sensor, *POI), "the calibration the database holds current")
    c.eq(d.get("/api/calibrations/%d" % cal["id"]).body, a.body,
         "the same bytes as the uncached GET /api/calibrations/{id}")

    # ---- every change is seen by the next read ----
    fits = [j["fit_id"]]
    for k, r_max in enumerate((3, 1, 4, 2, 3)):
        d.get(pix)  # the cache holds the old calibration now
        j = upload(r_max)
        c.ok(j, "upload %d fitted" % (k + 2))
        got = d.get(pix).json()
        c.eq((got["id"], got["fit_id"], got["current"]),
             (current_in_db(db, sensor, *POI), j["fit_id"] if j else None, True),
             "upload %d: the next read shows the new current calibration" % (k + 2))
        fits.append(j["fit_id"] if j else 0)
    d.get(pix)
    r = d.post("/api/fits/%d/promote" % fits[0], {"by": "cache-test", "reason": "back"})
    c.status(r, 201, "promote the first fit again")
    got = d.get(pix).json()
    c.eq((got["id"], got["fit_id"], got["by"]),
         (current_in_db(db, sensor, *POI), fits[0], "cache-test"),
         "after a promote the next read shows the promoted calibration")
    c.eq(d.get(pix).body, d.get("/api/calibrations/%d" % got["id"]).body,
         "the cached bytes equal the uncached endpoint's after the promote")

    # ---- CSV: not cached, and agrees with the JSON ----
    h2 = counters()
    csv = d.get(pix + "?format=csv")
    c.status(csv, 200, "CSV read")
    lines = csv.text.strip().split("\n")
    c.eq(len(lines) - 1, got["r"] * got["r"], "CSV: one line per sub-pixel")
    c.ok(all(line.startswith("%d," % got["id"]) for line in lines[1:]),
         "CSV: every line names the current calibration")
    c.eq(counters(), h2, "CSV reads touch no cache counter")

    db.close()
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
