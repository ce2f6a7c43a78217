#!/usr/bin/env python3
"""test_server_scanend.py IPSD: the end of a scan is one transaction: the scan becomes
done, its automatic fit is queued and its job ends together (storage_scan_finish). As three
transactions, a user's re-fit queued in the window after the scan became done made the scanner
skip the automatic fit (it queued one only when the scan had no fit job). The failpoint
scan.finish (docs/server.md "Test hooks") holds the scan at its end, before that transaction:
there the scan is still running, so a re-fit is refused (409), and once released the scan has
its automatic fit (by ipsd, promoted: the calibration), whatever came before. A crash at the same
point: the next start finishes the scan once, with one automatic fit."""
import json
import sys

import ipsd_http
from ipsd_http import Db, Ipsd

RASTER = {"area_px": 1, "step_um": 2, "sub_px": 3, "frames": 1}


def fit_jobs(db, scan):
    """The scan's fit jobs, oldest first: (id, by, promote) from the stored params."""
    rows = db.all("SELECT id, params FROM jobs WHERE scan_id = ? AND kind = 'fit' ORDER BY id",
                  scan)
    return [(i, json.loads(p).get("by"), json.loads(p).get("promote")) for i, p in rows]


def test(c, t, argv, daemons):
    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start("--workers", "1", failpoints="scan.finish=hold")
    db = Db(d.db)
    sensor = d.post("/api/sensors", {"model": "END", "serial": "1"}).json()["id"]
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 10, "row": 10},
                              "raster": RASTER})
    c.status(r, 202, "a small scan")
    scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
    total = r.json()["scan"]["raster"]["points_total"]
    c.ok(d.wait_held("scan.finish", job), "the scan is held at its end")
    s = d.get("/api/scans/%d" % scan).json()
    c.eq((s["state"], s["points_done"]), ("running", total),
         "every point stored, the scan not yet done")
    c.eq(fit_jobs(db, scan), [], "no fit job yet")
    # the user's re-fit in the window: refused, since the scan is not done
    r = d.post("/api/scans/%d/fits" % scan, {"dcol": 0, "drow": 0})
    c.error(r, 409, "", "a re-fit before the scan's end is refused")
    d.release("scan.finish", job)
    c.ok(d.wait_job(job, "done"), "the scan job ends as done")
    auto = fit_jobs(db, scan)
    c.eq([(b, p) for _, b, p in auto], [("ipsd", True)],
         "the scan has its automatic fit: by ipsd, promoted")
    c.eq(db.one("SELECT state FROM scans WHERE id = ?", scan), ("done",), "the scan is done")
    c.ok(auto and d.wait_job(auto[0][0], "done"), "the automatic fit runs to done")
    cal = d.get("/api/sensors/%d/pixels/10/10/calibration" % sensor)
    c.status(cal, 200, "the pixel has its calibration")
    c.eq(cal.json().get("by"), "ipsd", "made by the automatic fit")
    # the re-fit now: queued after the automatic one, which it does not replace
    r = d.post("/api/scans/%d/fits" % scan, {"dcol": 0, "drow": 0})
    c.status(r, 202, "a re-fit of the done scan")
    c.eq([b for _, b, _ in fit_jobs(db, scan)], ["ipsd", None],
         "the automatic fit first, then the user's")
    c.ok(d.wait_job(r.json()["job"]["id"], "done"), "the re-fit runs")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")

    # a crash at the scan's end: nothing of the end is stored; the next start finishes it once
    # held at the end first, crashing when released (the 202 comes before the crash)
    d.start("--workers", "1", failpoints="scan.finish=hold;scan.finish=crash")
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 12, "row": 12},
                              "raster": RASTER})
    c.status(r, 202, "submit a scan (to crash at its end)")
    scan2, job2 = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.release_when_held("scan.finish", job2), "the scan is held at its end")
    c.ok(ipsd_http.wait_for(lambda: d.proc.poll() is not None), "ipsd crashed at the end")
    d.proc = None
    c.eq(db.one("SELECT s.state, j.state FROM scans s JOIN jobs j ON j.scan_id = s.id "
                "WHERE j.id = ?", job2), ("running", "running"),
         "after the crash: scan and job still running")
    c.eq(fit_jobs(db, scan2), [], "and no fit job")
    d.start("--workers", "1")
    c.ok(d.wait_job(job2, "done"), "the next start finishes the scan")
    c.eq([(b, p) for _, b, p in fit_jobs(db, scan2)], [("ipsd", True)],
         "with one automatic fit")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
