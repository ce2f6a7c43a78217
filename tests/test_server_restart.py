#!/usr/bin/env python3
"""test_server_restart.py IPSD: jobs survive restarts, and cancel does what it says, with every
job stopped at a known point by a failpoint (docs/server.md, "Test hooks") instead of a race with
the fast simulated bench. A scan held at its 100th point and killed (kill -9) resumes at the next
start and ends with every raster point stored exactly once (rows counted and indexes checked with
Python's sqlite3 module), and a crashed ipsd leaves no stale lock (a second ipsd on the same
database is refused while the first runs); SIGTERM exits 0 and gives the held scan back to the
queue; a fit left running by a crash runs again; cancel works on queued and running jobs (scans
and fits) and is refused (409) for finished ones; a scan whose setup fails ends failed; a fit held
between its steps stops at SIGTERM and runs again at the next start."""
import json
import math
import os
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd


def upload_body(n):
    """An uploaded scan file of n points spread over a 6 um pixel (a smooth response)."""
    x = [0.3 + 5.4 * ((i * 0.618034) % 1) for i in range(n)]
    y = [0.3 + 5.4 * ((i * 0.414214) % 1) for i in range(n)]
    s = [100 + 5000 * math.exp(-((a - 3) ** 2 + (b - 3) ** 2) / 8) for a, b in zip(x, y)]
    return {"scan": {"pitch_um": 6, "spot_radius_um": 1.342, "bias_dn": 100,
                     "gain_e_per_dn": 3.153, "read_noise_e": 5.67, "frames": 12,
                     "x_um": x, "y_um": y, "signal_dn": s}}


def test(c, t, argv, daemons):
    exe = argv[1]
    d = Ipsd(exe, t)
    daemons.append(d)
    db = None

    def points_stored(scan):
        return db.val("SELECT count(*) FROM frames WHERE scan_id = ?", scan)

    def exactly_once(scan, total):
        """rows, distinct indexes, min and max are total, total, 0, total - 1"""
        return db.one("SELECT count(*), count(DISTINCT point_index), min(point_index), "
                      "max(point_index) FROM frames WHERE scan_id = ?", scan) == \
            (total, total, 0, total - 1)

    def submit(body):
        r = d.post("/api/scans", body)
        c.status(r, 202, "submit scan at %r" % (body["poi"],))
        return r.json()["scan"]["id"], r.json()["job"]["id"]

    def fits_done(scan):
        """Until every fit job of scan is done (so no fit runs across a restart)."""
        items = d.get("/api/jobs?kind=fit&scan=%d" % scan).json()["items"]
        return all(d.wait_job(j["id"], "done") for j in items) and len(items) > 0

    # ---- kill -9 in the middle of a scan (held after its 100th point) ----
    d.start(failpoints="scan.point=hold@100")
    db = Db(d.db)
    # one ipsd per database: a second one on the same file refuses to start (it would requeue the
    # first one's running jobs), naming the reason
    second = subprocess.run([exe, "--listen", "127.0.0.1:0", "--db", d.db],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                            timeout=ipsd_http.DEADLINE_S)
    c.eq(second.returncode, 1, "a second ipsd on the same database exits 1")
    c.ok("in use by another ipsd" in second.stderr, "the second ipsd says why: " + second.stderr)
    r = d.post("/api/sensors", {"model": "IMX-R", "serial": "restart-1"})
    sensor = r.json()["id"]
    small = {"sensor_id": sensor, "poi": {"col": 30, "row": 30},
             "raster": {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}}
    s1, j1 = submit(small)
    c.ok(d.wait_held("scan.point", j1), "scan 1 held after its 100th point")
    c.eq(points_stored(s1), 100, "scan 1 reaches 100 points")
    p0 = db.val("SELECT hex(mean) FROM frames WHERE scan_id = ? AND point_index = 0", s1)
    d.stop_kill()
    n1 = points_stored(s1)
    c.ok(n1 < 961, "killed mid-scan (%d points)" % n1)
    c.eq(db.val("SELECT state FROM jobs WHERE id = ?", j1), "running", "left running by the crash")
    os.remove(d.held_path("scan.point", j1))  # the crash left it

    d.start()
    c.ok(d.wait_job(j1, "done"), "resumed scan done")
    c.ok(exactly_once(s1, 961), "every point exactly once after the crash")
    c.eq(db.val("SELECT hex(mean) FROM frames WHERE scan_id = ? AND point_index = 0", s1), p0,
         "points stored before the crash kept")
    c.eq(db.val("SELECT attempts FROM jobs WHERE id = ?", j1), 2, "claimed twice")
    c.ok("1 interrupted job(s) queued again" in d.log_text(), "start-up requeue logged")
    r = d.get("/api/scans/%d" % s1).json()
    c.eq((r["state"], r["points_done"]), ("done", 961), "scan 1 done with 961 points")
    c.ok(fits_done(s1), "scan 1's automatic fit done")
    c.eq(d.stop_term(), 0, "SIGTERM with nothing running: exit status 0")

    # ---- SIGTERM in the middle of a scan: exit 0, the scan resumes at the next start ----
    d.start(failpoints="scan.point=hold@100")
    s2, j2 = submit(dict(small, poi={"col": 30, "row": 40}))
    c.ok(d.wait_held("scan.point", j2), "scan 2 reaches 100 points")
    c.eq(d.stop_term(), 0, "SIGTERM mid-scan: exit status 0")
    n2 = points_stored(s2)
    c.eq(n2, 100, "stopped mid-scan, at the held point")
    c.eq(db.one("SELECT state, attempts FROM jobs WHERE id = ?", j2), ("queued", 0),
         "job given back: queued, claim not counted")
    c.eq(db.val("SELECT state FROM scans WHERE id = ?", s2), "running",
         "scan stays running (to resume)")
    c.eq(db.val("SELECT points_done FROM scans WHERE id = ?", s2), n2, "points_done = rows")
    c.ok(not os.path.exists(d.held_path("scan.point", j2)), "the stop removed the held file")
    c.ok("failpoint scan.point: job %d no longer held" % j2 in d.log_text(),
         "the stop ended the hold (logged)")

    # a fit job a crash left running (as the row looks after kill -9 during a fit)
    db.all("INSERT INTO jobs (kind, params, state, attempts, heartbeat_ms, created_ms, "
           "started_ms, scan_id) VALUES ('fit', ?, 'running', 1, 1, 1, 1, ?)",
           json.dumps({"scan_id": s1, "dcol": 0, "drow": 1, "r_min": 1, "r_max": 3}), s1)
    jf = db.val("SELECT max(id) FROM jobs")
    d.start()
    c.ok(d.wait_job(j2, "done"), "scan 2 resumed to done")
    c.ok(exactly_once(s2, 961), "every point of scan 2 exactly once after SIGTERM")
    c.ok(d.wait_job(jf, "done"), "interrupted fit ran again")
    c.eq(db.val("SELECT count(*) FROM calibrations WHERE pixel_col = 30 AND pixel_row = 31"), 1,
         "its calibration (pixel 30, 31) stored")
    c.ok(fits_done(s2), "scan 2's automatic fit done")
    c.eq(d.stop_term(), 0, "SIGTERM with nothing running: exit status 0")

    # ---- cancel: a running scan (held at its 20th point) and a queued one; a failing setup;
    # fits held at their first step: cancelled, and stopped by SIGTERM ----
    d.start(failpoints="scan.point=hold@20;scan.setup=error@2;fit.step=hold")
    long_scan = {"sensor_id": sensor, "poi": {"col": 80, "row": 80},
                 "raster": {"area_px": 5, "step_um": 0.6, "sub_px": 3, "frames": 1}}
    s3, j3 = submit(long_scan)
    s4, j4 = submit(dict(long_scan, poi={"col": 80, "row": 90}))
    c.ok(d.wait_held("scan.point", j3), "scan 3 running (held at its 20th point)")
    r = d.post("/api/scans/%d/cancel" % s4)
    c.status(r, 200, "cancel a queued scan")
    c.eq((r.json()["scan"]["state"], r.json()["job"]["state"]), ("cancelled", "cancelled"),
         "queued scan cancelled")
    c.error(d.post("/api/scans/%d/cancel" % s4), 409, "", "cancel it again")
    c.status(d.post("/api/jobs/%d/cancel" % j3), 200, "cancel the running scan's job")
    c.ok(d.wait_job(j3, "cancelled"), "running job cancelled")
    # the cancel ends the hold: the worker removes the held file and stores no further point
    c.ok(d.wait_hold_ended("scan.point", j3), "the cancel ended the hold")
    n3 = points_stored(s3)
    c.eq(n3, 20, "no point stored after the cancel")
    c.ok(n3 < 2601, "cancelled scan stopped short")
    c.eq(db.val("SELECT state FROM scans WHERE id = ?", s3), "cancelled", "scan 3 cancelled")
    c.eq(db.val("SELECT count(*) FROM jobs WHERE kind = 'fit' AND scan_id = ?", s3), 0,
         "no fit queued for a cancelled scan")
    c.eq(points_stored(s4), 0, "cancelled queued scan never ran")
    c.error(d.post("/api/jobs/%d/cancel" % j1), 409, "", "cancel a finished job")
    c.error(d.post("/api/scans/%d/fits" % s3, {}), 409, "", "fit a scan that is not done")

    # the next scan's setup (the 2nd of this run) fails: the scan and its job fail, saying why
    s5, j5 = submit(dict(long_scan, poi={"col": 90, "row": 80}))
    j = d.wait_job(j5, "failed")
    c.ok(j and "failpoint scan.setup: injected error" in (j.get("error") or ""),
         "a failing setup fails the job with its error: %r" % (j and j.get("error")))
    c.eq((db.val("SELECT state FROM scans WHERE id = ?", s5), points_stored(s5)), ("failed", 0),
         "the failed scan is failed, with no point")
    c.eq(db.val("SELECT count(*) FROM jobs WHERE kind = 'fit' AND scan_id = ?", s5), 0,
         "no fit queued for a failed scan")

    # a fit held after its first step (r = 1): cancel it while it runs, and SIGTERM another
    fits0 = db.val("SELECT count(*) FROM fits")
    body = upload_body(300)
    r = d.post("/api/fits", body)
    c.status(r, 202, "upload a fit")
    jl = r.json()["job"]["id"]
    c.ok(d.wait_held("fit.step", jl), "long fit running (held after its first step)")
    c.eq(d.job_state(jl), "running", "held fit job running")
    c.status(d.post("/api/jobs/%d/cancel" % jl), 200, "cancel a running fit")
    c.ok(d.wait_hold_ended("fit.step", jl), "the cancel ended the fit's hold")
    r = d.post("/api/fits", body)
    jt = r.json()["job"]["id"]
    c.ok(d.wait_held("fit.step", jt), "second long fit running (held after its first step)")
    c.eq(d.job_state(jt), "running", "second held fit job running")
    # held, the fit would never end by itself: ipsd exiting shows the stop did not wait for it
    c.eq(d.stop_term(), 0, "SIGTERM during a fit: exit status 0")
    c.ok("failpoint fit.step: job %d no longer held" % jt in d.log_text(),
         "the stop did not wait for the whole fit (it ended the hold)")
    c.eq(db.one("SELECT state, attempts FROM jobs WHERE id = ?", jt), ("queued", 0),
         "the fit given back: queued, claim not counted")
    c.eq(db.one("SELECT state, fit_id IS NULL FROM jobs WHERE id = ?", jl), ("cancelled", 1),
         "the cancelled fit stored nothing")
    c.eq(db.val("SELECT count(*) FROM fits"), fits0, "no fit stored meanwhile")

    d.start()
    c.ok(d.wait_job(jt, "done", 120), "the fit given back runs again to done")
    c.eq(db.val("SELECT count(*) FROM fits"), fits0 + 1, "one fit stored")
    c.eq(db.one("SELECT state, fit_id IS NULL FROM jobs WHERE id = ?", jl), ("cancelled", 1),
         "the cancelled fit did not run again")
    db.close()
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
