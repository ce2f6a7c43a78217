#!/usr/bin/env python3
"""test_server_fitstop.py IPSD: a cancel and SIGTERM stop a fit inside a step, not only between
steps. The fit is held by the failpoint fit.poll (docs/server.md "Test
hooks") at its first poll of the stop: the design matrix's first batch of its first r, before any
step ended (progress 0). (A later poll is not safe: how many polls a step makes follows the design's
batching, and the 3rd fell in the second r once the first took one batch: its progress then
reached the job's row whenever the first step outlasted the 1 s heartbeat, i.e. on a busy machine.) The hold ends only through the worker's stop flag, so the job ending proves
that the stop set by the cancel (or by SIGTERM) unwinds the fit from inside its loop: the job is
cancelled with nothing stored and the worker takes the next job; at SIGTERM ipsd exits 0 and the
job goes back to the queue, then runs to done at the next start. The latency is measured in
bench (the report), not asserted here. The same inside the LM (the point fit.poll.lm, hit only by
the LM's own polls): a cancel and a SIGTERM there end the fit from inside its iterations. The same
inside the other long loops, each held at the first hit of its own point ("between r and
inside the long loops"): the non-negative solve's active-set steps (fit.poll.nnls, "nonneg": true),
the Wiener baseline's kernel and FFT passes (fit.poll.wiener, "wiener": true on the reference
raster, after the sweep's steps) and the geometry fit's iterations (fit.poll.geometry, "fit_geometry":
true). Then the fit request's limits: --max-fit-points (413
naming scan.x_um) and --max-fit-r (422 naming r_max, ftest_r or geometry_r)."""
import json
import math
import os
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd


def upload_body(n, r_max):
    x = [0.3 + 5.4 * ((i * 0.618034) % 1) for i in range(n)]
    y = [0.3 + 5.4 * ((i * 0.414214) % 1) for i in range(n)]
    s = [100 + 5000 * math.exp(-((a - 3) ** 2 + (b - 3) ** 2) / 8) for a, b in zip(x, y)]
    return {"scan": {"pitch_um": 6, "spot_radius_um": 1.342, "bias_dn": 100,
                     "gain_e_per_dn": 3.153, "read_noise_e": 5.67, "frames": 12,
                     "x_um": x, "y_um": y, "signal_dn": s}, "r_max": r_max}


def paperlike_body(r_max):
    """The reference scan (tests/data: a 9 x 9 raster of the simulated bench, which the Wiener
    baseline needs and on which the geometry fit converges in a few iterations)."""
    with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "data",
                           "paperlike_scan.json")) as f:
        return {"scan": json.load(f), "r_max": r_max}


def site_stops(c, d, db, fits):
    """A cancel, then a SIGTERM, while a fit is held at the first poll inside each loop; fits is
    the count of fits stored so far. Returns the count after."""
    for site, body, why in (
            ("nnls", dict(upload_body(400, 6), nonneg=True), "the non-negative solve"),
            ("wiener", dict(paperlike_body(2), wiener=True), "the Wiener baseline"),
            ("geometry", dict(paperlike_body(2), fit_geometry=True, geometry_r=3),
             "the geometry fit")):
        point = "fit.poll." + site
        d.start("--workers", "1", failpoints=point + "=hold@1")
        r = d.post("/api/fits", body)
        c.status(r, 202, "a fit that runs %s" % why)
        job = r.json()["job"]["id"]
        c.ok(d.wait_held(point, job), "held at the first poll inside %s" % why)
        c.ok("failpoint %s: holding job %d at hit 1" % (point, job) in d.log_text(),
             "the log names %s's poll" % point)
        c.eq(d.job_state(job), "running", "the fit is running, inside %s" % why)
        c.status(d.post("/api/jobs/%d/cancel" % job), 200, "cancel it there")
        c.ok(d.wait_hold_ended(point, job), "the cancel's stop flag ended the hold in %s" % why)
        c.ok(d.wait_job(job, "cancelled"), "the job is cancelled")
        c.eq(db.one("SELECT state, fit_id IS NULL FROM jobs WHERE id = ?", job), ("cancelled", 1),
             "the fit cancelled inside %s stored nothing" % why)
        c.eq(db.val("SELECT count(*) FROM fits"), fits, "no fit was added")
        c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")
        # SIGTERM while held there: ipsd exits, the job goes back to the queue, runs again
        d.start("--workers", "1", failpoints=point + "=hold@1")
        job = d.post("/api/fits", body).json()["job"]["id"]
        c.ok(d.wait_held(point, job), "a second fit held inside %s" % why)
        c.eq(d.stop_term(), 0, "SIGTERM inside %s: exit status 0" % why)
        c.eq(db.one("SELECT state, attempts, fit_id IS NULL FROM jobs WHERE id = ?", job),
             ("queued", 0, 1), "the fit stopped inside %s given back: queued, nothing stored" % why)
        d.start("--workers", "1")
        c.ok(d.wait_job(job, "done"), "it runs again to done")
        fits += 1
        c.eq(db.val("SELECT count(*) FROM fits"), fits, "and stores its one fit")
        if site != "nnls":  # the part's own result, not {"error": ...}
            part = json.loads(db.val("SELECT result FROM fits ORDER BY id DESC LIMIT 1")).get(site)
            c.ok(isinstance(part, dict) and "error" not in part,
                 "%s ran to its end in the rerun: %.200r" % (why, part))
        c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")
    return fits


def test(c, t, argv, daemons):
    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start("--workers", "1", failpoints="fit.poll=hold@1")
    db = Db(d.db)
    r = d.post("/api/fits", upload_body(400, 6))
    c.status(r, 202, "upload a fit")
    job = r.json()["job"]["id"]
    nxt = d.post("/api/fits", upload_body(60, 2)).json()["job"]["id"]
    c.ok(d.wait_held("fit.poll", job), "the fit is held inside its first step")
    j = d.get("/api/jobs/%d" % job).json()
    c.eq((j["state"], j["progress"]), ("running", 0.0), "running, no step ended yet")
    c.eq(d.job_state(nxt), "queued", "the next job waits for the one worker")
    c.status(d.post("/api/jobs/%d/cancel" % job), 200, "cancel the fit inside its step")
    c.ok(d.wait_hold_ended("fit.poll", job), "the cancel's stop flag ended the hold")
    c.ok(d.wait_job(job, "cancelled"), "the job is cancelled")
    c.ok(d.wait_job(nxt, "done"), "the worker takes the next job")
    c.eq(db.one("SELECT state, fit_id IS NULL FROM jobs WHERE id = ?", job), ("cancelled", 1),
         "the cancelled fit stored nothing")
    c.eq(db.val("SELECT count(*) FROM fits"), 1, "only the next job's fit is stored")
    c.ok("failpoint fit.step" not in d.log_text(), "no step of the fit ended")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")

    # SIGTERM while the fit is held inside its step: ipsd exits, the job goes back to the queue
    d.start("--workers", "1", failpoints="fit.poll=hold@1")
    r = d.post("/api/fits", upload_body(400, 6))
    job = r.json()["job"]["id"]
    c.ok(d.wait_held("fit.poll", job), "a second fit held inside its first step")
    c.eq(d.stop_term(), 0, "SIGTERM during the step: exit status 0")
    c.eq(db.one("SELECT state, attempts, fit_id IS NULL FROM jobs WHERE id = ?", job),
         ("queued", 0, 1), "the fit given back: queued, claim not counted, nothing stored")
    d.start("--workers", "1")
    c.ok(d.wait_job(job, "done"), "it runs again to done")
    c.eq(db.val("SELECT count(*) FROM fits"), 2, "and stores its one fit")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")

    # inside the LM: the point fit.poll.lm is hit only by the polls inside lm.c (each iteration,
    # Jacobian and residual), so a hold there is a fit inside its LM whatever the count of the
    # design-matrix and solve polls before it. Its 3rd hit is past the start (init's residual and
    # Jacobian): inside the iterations of the first r. A cancel there ends the hold through the
    # stop flag, and the fit unwinds from the LM with nothing stored.
    d.start("--workers", "1", failpoints="fit.poll.lm=hold@3")
    body = upload_body(400, 6)
    body.update(method="lm")
    job = d.post("/api/fits", body).json()["job"]["id"]
    c.ok(d.wait_held("fit.poll.lm", job), "an LM fit held at a poll inside its LM")
    c.ok("failpoint fit.poll.lm: holding job %d at hit 3" % job in d.log_text(),
         "the log names the LM's poll and its hit")
    j = d.get("/api/jobs/%d" % job).json()
    c.eq((j["state"], j["progress"]), ("running", 0.0), "running inside the first r's LM")
    c.status(d.post("/api/jobs/%d/cancel" % job), 200, "cancel the fit inside its LM")
    c.ok(d.wait_hold_ended("fit.poll.lm", job), "the cancel's stop flag ended the hold in the LM")
    c.ok(d.wait_job(job, "cancelled"), "the job is cancelled")
    c.eq(db.one("SELECT state, fit_id IS NULL FROM jobs WHERE id = ?", job), ("cancelled", 1),
         "the fit cancelled in its LM stored nothing")
    c.eq(db.val("SELECT count(*) FROM fits"), 2, "no fit was added")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")
    # SIGTERM inside the LM: the fit unwinds from there, ipsd exits 0, the job is given back
    d.start("--workers", "1", failpoints="fit.poll.lm=hold@3")
    job = d.post("/api/fits", body).json()["job"]["id"]
    c.ok(d.wait_held("fit.poll.lm", job), "a second LM fit held inside its LM")
    c.eq(d.stop_term(), 0, "SIGTERM inside the LM: exit status 0")
    c.eq(db.one("SELECT state, attempts, fit_id IS NULL FROM jobs WHERE id = ?", job),
         ("queued", 0, 1), "the fit stopped in its LM given back: queued, nothing stored")
    d.start("--workers", "1")
    c.ok(d.wait_job(job, "done"), "it runs again to done")
    c.eq(db.val("SELECT count(*) FROM fits"), 3, "and stores its one fit")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")

    site_stops(c, d, db, 3)

    # the limits of a fit request (--max-fit-points, --max-fit-r): 413 / 422 naming the field
    d.start("--workers", "1", "--max-fit-points", "100", "--max-fit-r", "4")
    c.error(d.post("/api/fits", upload_body(101, 4)), 413, "scan.x_um", "101 points over 100")
    c.error(d.post("/api/fits", upload_body(100, 5)), 422, "r_max", "r_max 5 over 4")
    b = upload_body(100, 4)
    b.update(ftest="top", ftest_r=5)
    c.error(d.post("/api/fits", b), 422, "ftest_r", "ftest_r 5 over 4")
    b = upload_body(100, 4)
    b.update(fit_geometry=True, geometry_r=5)
    c.error(d.post("/api/fits", b), 422, "geometry_r", "geometry_r 5 over 4")
    r = d.post("/api/fits", upload_body(100, 4))
    c.status(r, 202, "100 points at r_max 4: at the limits, accepted")
    c.ok(d.wait_job(r.json()["job"]["id"], "done"), "and fitted")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")
    for flag, bad in (("--max-fit-points", "0"), ("--max-fit-r", "33")):
        p = subprocess.run([argv[1], "--db", d.db, flag, bad], stderr=subprocess.PIPE,
                           stdout=subprocess.DEVNULL, text=True, timeout=ipsd_http.DEADLINE_S)
        c.ok(p.returncode == 2 and flag in p.stderr, "%s %s refused: %r" % (flag, bad, p.stderr))
    db.close()


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
