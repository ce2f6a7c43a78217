#!/usr/bin/env python3
"""test_server_crash.py IPSD: a crash at any point of a fit job loses nothing and writes nothing
twice. ipsd is killed (SIGKILL, by the `crash` failpoint action:
docs/server.md "Test hooks") at each named point of a fit's end: during the fit (fit.step),
after the fit is computed but before it is stored (fit.before_store), and after the store's
transaction (fit.after_store). It is started again without failpoints, and Python's sqlite3
module, reading the database independently, checks after each crash: the job is done, exactly
one fit and one fit map are stored for it and linked to it, its pixel has exactly one
calibration (the one of that fit), and no fit is orphaned (every fit is some job's). Before the
fit's store and the job's `done` were one transaction, a crash at fit.after_store left the job
running; the restart ran it again: a second fit and a second calibration, the first fit
orphaned. Both kinds of fit job are crashed: an uploaded scan file with a target pixel, and the
automatic fit of a finished scan."""
import math
import os
import sys

import ipsd_http
from ipsd_http import Db, Ipsd, wait_for


def upload_body(n, sensor, col, row):
    """An uploaded scan file of n points over a 6 um pixel (a smooth response), fitted at
    r = 1..4, its map stored as the calibration of sensor's pixel (col, row)."""
    x = [0.3 + 5.4 * ((i * 0.618034) % 1) for i in range(n)]
    y = [0.3 + 5.4 * ((i * 0.414214) % 1) for i in range(n)]
    s = [100 + 5000 * math.exp(-((a - 3) ** 2 + (b - 3) ** 2) / 8) for a, b in zip(x, y)]
    return {"scan": {"pitch_um": 6, "spot_radius_um": 1.342, "bias_dn": 100,
                     "gain_e_per_dn": 3.153, "read_noise_e": 5.67, "frames": 12,
                     "x_um": x, "y_um": y, "signal_dn": s},
            "sensor_id": sensor, "pixel": {"col": col, "row": row}, "r_max": 4}


def wait_crash(c, d, point):
    """Until ipsd killed itself at point: SIGKILL, and the log names the point."""
    c.eq(d.wait_exit(), -9, "ipsd crashed (SIGKILL) at %s" % point)
    c.ok("failpoint %s: crashing" % point in d.log_text(), "the crash at %s is logged" % point)


def test(c, t, argv, daemons):
    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start()
    db = Db(d.db)
    r = d.post("/api/sensors", {"model": "IMX-C", "serial": "crash-1", "pitch_um": 6})
    c.status(r, 201, "create a sensor")
    sensor = r.json()["id"]
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")

    def consistent(job, col, row, attempts, what):
        """The database after a crash of job (fitting sensor pixel (col, row)) and a restart."""
        state, fit, tries = db.one("SELECT state, fit_id, attempts FROM jobs WHERE id = ?", job)
        c.eq(state, "done", "%s: the job is done" % what)
        c.ok(fit is not None, "%s: the job names its fit" % what)
        c.eq(tries, attempts, "%s: the job was claimed %d time(s)" % (what, attempts))
        c.eq(db.val("SELECT count(*) FROM fits WHERE id = ?", fit), 1, "%s: its fit exists" % what)
        c.eq(db.val("SELECT count(*) FROM fit_maps WHERE sensor_id = ? AND pixel_col = ? AND "
                    "pixel_row = ?", sensor, col, row), 1, "%s: one fit map of the pixel" % what)
        c.eq(db.all("SELECT fit_id FROM calibrations WHERE sensor_id = ? AND pixel_col = ? AND "
                    "pixel_row = ?", sensor, col, row), [(fit,)],
             "%s: one calibration of the pixel, the job's fit's" % what)
        # nothing orphaned anywhere: every fit is the fit of exactly one job, every map a fit's
        c.eq(db.val("SELECT count(*) FROM fits WHERE id NOT IN "
                    "(SELECT fit_id FROM jobs WHERE fit_id IS NOT NULL)"), 0,
             "%s: no orphaned fit" % what)
        c.eq(db.val("SELECT count(*) FROM (SELECT fit_id FROM jobs WHERE fit_id IS NOT NULL "
                    "GROUP BY fit_id HAVING count(*) > 1) shared"), 0, "%s: no fit shared by jobs" % what)
        c.eq(db.val("SELECT count(*) FROM fits"),
             db.val("SELECT count(*) FROM jobs WHERE kind = 'fit' AND state = 'done'"),
             "%s: one fit per done fit job" % what)
        c.eq(db.val("SELECT count(*) FROM calibrations WHERE fit_id NOT IN (SELECT id FROM fits)"),
             0, "%s: every calibration's fit exists" % what)

    # ---- an uploaded fit killed at each point; the restart finishes it exactly once ----
    # (point, the claims the job takes: a crash before the commit runs the fit again, one after
    # it finds the job done)
    cases = [("fit.step", 2), ("fit.before_store", 2), ("fit.after_store", 1)]
    for i, (point, attempts) in enumerate(cases):
        # held there first, crashing when released: the upload's 202 comes before the crash (a
        # crash at the fit's first step could come before the HTTP thread had answered)
        d.start(failpoints="%s=hold@1;%s=crash@1" % (point, point))
        r = d.post("/api/fits", upload_body(150, sensor, 10 + i, 20))
        c.status(r, 202, "upload a fit to crash at %s" % point)
        job = r.json()["job"]["id"]
        c.ok(d.release_when_held(point, job), "the fit is held at %s" % point)
        wait_crash(c, d, point)
        if point == "fit.after_store":
            c.eq(db.val("SELECT state FROM jobs WHERE id = ?", job), "done",
                 "killed after the store's commit: the job is already done")
        else:
            c.eq(db.one("SELECT state, fit_id FROM jobs WHERE id = ?", job), ("running", None),
                 "killed before the store: the job is left running with no fit")
        d.start()
        c.ok(d.wait_job(job, "done"), "after the crash at %s the job ends done" % point)
        consistent(job, 10 + i, 20, attempts, "upload, crash at " + point)
        c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")

    # ---- the automatic fit of a finished scan, killed after its store ----
    d.start(failpoints="fit.after_store=hold@1;fit.after_store=crash@1")
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 30, "row": 30},
                              "raster": {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}})
    c.status(r, 202, "submit a scan")
    scan, scan_job = r.json()["scan"]["id"], r.json()["job"]["id"]
    auto = wait_for(lambda: db.val("SELECT id FROM jobs WHERE kind = 'fit' AND scan_id = ?", scan))
    c.ok(auto and d.release_when_held("fit.after_store", auto),
         "the automatic fit is held after its store")
    wait_crash(c, d, "fit.after_store")
    d.start()
    c.ok(d.wait_job(scan_job, "done"), "the scan's job is done")
    jobs = db.all("SELECT id FROM jobs WHERE kind = 'fit' AND scan_id = ?", scan)
    c.eq(len(jobs), 1, "one automatic fit job for the scan")
    if jobs:
        c.ok(d.wait_job(jobs[0][0], "done"), "the automatic fit is done")
        consistent(jobs[0][0], 30, 30, 1, "scan, crash at fit.after_store")
    c.eq(db.val("SELECT count(*) FROM fits WHERE scan_id = ?", scan), 1, "one fit of the scan")
    db.close()
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
