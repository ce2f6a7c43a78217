#!/usr/bin/env python3
"""test_server_allpixels.py IPSD IPS: every pixel a scan covers.

A simulated paper-like scan (the paper's raster: 5 x 5 pixels of 6 um in 0.6 um steps, with a
7 x 7 sub-frame) is fitted for all pixels with one request (POST /api/scans/{id}/fits with
"pixels": "all"):
- coverage (GET /api/scans/{id}/coverage): the 25 pixels of the 5 x 5 raster are covered, each
  with (6 / 0.6 - 1)^2 = 81 positions strictly inside (arithmetic of the raster, not the code's
  numbers); the other 24 of the 7 x 7 sub-frame are "not_covered" with a reason, and never get a
  fit or a calibration;
- cancel mid-way: a job held after its 3rd pixel (failpoint fit.pixel=hold@3) and cancelled keeps
  exactly the 3 pixels it stored, and stores nothing more;
- crash after k pixels: a job killed (fit.pixel=crash@5) after its 5th pixel resumes after the
  restart at the 6th: in the end every covered pixel has exactly one fit and one calibration of
  that job, none twice (the database read with Python's sqlite3);
- progress: the job's events count pixels, points_done k of points_total 25, in order, each
  naming its pixel (and, once stored, the pixel's fit: the database's dcol, drow of that fit);
- the job's answer lists the fits it stored (fit_ids: the database's fits after the job began,
  in order; fit_id the newest; the list GET /api/jobs too) and every pixel of the sub-frame:
  fitted with a fit of that pixel, not_fitted (a cancelled job), or not_covered with the reason;
- each covered pixel's calibration (the simulated sensor's pixels all share the scene's map)
  matches the simulator's known truth for that map (`ips simulate --truth`): every sub-pixel
  within K_SIGMA of its error plus MODEL (below)."""
import json
import math
import os
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, EventStream, Ipsd, wait_for

SUB = 7          # the sub-frame: 7 x 7 pixels
AREA = 5         # the raster: 5 x 5 pixels
STEP = 0.6       # um, on 6 um pixels: 10 steps a pixel
INSIDE = (round(6 / STEP) - 1) ** 2  # positions strictly inside a covered pixel: 9 x 9
COVERED = {(dc, dr) for dc in range(-2, 3) for dr in range(-2, 3)}
# A calibration against the truth: the recommended map's sub-pixels lie within K_SIGMA of their
# 1-sigma errors of the truth's sub-pixel mean (625 values in all: 4 sigma leaves a Gaussian
# excursion a chance of ~4 % over all of them), plus MODEL for the bias of an r x r map fitted to a
# 30 x 30-cell scene seen through a 1.3 um spot (measured: the largest |S - truth| / S_err of the
# 25 maps is 3.2, the median S_err 0.028, so a map mirrored or of another pixel's 25-30 % edge
# dips would fail).
K_SIGMA = 4
MODEL = 0.02


def truth_maps(ips, tmp):
    """The simulator's paperlike map averaged over r x r sub-pixels (mean 1), r = 1..10."""
    path = os.path.join(tmp, "truth.json")
    subprocess.run([ips, "simulate", "--scene", "paperlike", "--grid", "3", "--frames", "1",
                    "--truth", path, "-o", os.path.join(tmp, "grid.json")], check=True,
                   stdout=subprocess.DEVNULL)
    with open(path) as f:
        return {m["r"]: m["S_normalised"] for m in json.load(f)["maps"]}


def check_job_fits(c, d, db, job, scan, after_id, n):
    """The job's answer lists the n fits it stored (the database's fits of the scan after
    after_id, an independent record), its fit_id the newest, and every pixel of the sub-frame with
    what the job did of it: its fit (of that pixel), not fitted, or not covered."""
    j = d.get("/api/jobs/%d" % job).json()
    ids = [i for (i,) in db.all("SELECT id FROM fits WHERE scan_id = ? AND id > ? ORDER BY id",
                                scan, after_id)]
    c.eq(j.get("fit_ids"), ids, "the job lists the %d fits it stored, in order" % n)
    c.eq(len(ids), n, "%d fits" % n)
    c.eq(j["fit_id"], ids[-1] if ids else None, "the job's fit_id is the newest")
    c.ok("fit_ids" not in j["params"], "the request's params stay as they were")
    listed = [x for x in d.get("/api/jobs?kind=fit&scan=%d&limit=100" % scan).json()["items"]
              if x["id"] == job]
    c.eq([x.get("fit_ids") for x in listed], [ids], "the list GET /api/jobs carries the same")
    where = {i: (a, b) for i, a, b in db.all("SELECT id, dcol, drow FROM fits WHERE id > ?",
                                            after_id)}
    px = {(p["dcol"], p["drow"]): p for p in j.get("pixels", [])}
    c.eq(len(px), SUB * SUB, "every pixel of the sub-frame is listed")
    fitted = {k for k, p in px.items() if p["status"] == "fitted"}
    c.eq(len(fitted), n, "%d fitted" % n)
    c.ok(all(where.get(px[k]["fit_id"]) == k for k in fitted), "each with a fit of that pixel")
    c.ok(all(px[k]["col"] == 40 + k[0] and px[k]["row"] == 50 + k[1] for k in px),
         "sensor coordinates")
    c.eq({k for k, p in px.items() if p["status"] == "not_covered" and p["reason"]},
         {(a, b) for a in range(-3, 4) for b in range(-3, 4)} - COVERED,
         "the pixels the raster misses are not_covered, with the reason")
    c.eq(sum(p["status"] == "not_fitted" for p in px.values()), 25 - n,
         "the covered pixels the job did not get to are not_fitted")


def test(c, t, argv, daemons):
    truth = truth_maps(argv[2], t)
    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start("--calibration-map", "recommended", failpoints="fit.pixel=hold@3")
    db = Db(d.db)
    r = d.post("/api/sensors", {"model": "IMX-A", "serial": "all-1", "pitch_um": 6})
    c.status(r, 201, "create a sensor")
    sensor = r.json()["id"]
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 40, "row": 50},
                              "raster": {"area_px": AREA, "step_um": STEP, "sub_px": SUB,
                                         "frames": 4}, "scene": "paperlike", "seed": 7})
    c.status(r, 202, "submit a 5 x 5-pixel scan with a 7 x 7 sub-frame")
    scan, scan_job = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_job(scan_job, "done"), "the scan is done")
    auto = db.val("SELECT id FROM jobs WHERE kind = 'fit' AND scan_id = ?", scan)
    c.ok(d.wait_job(auto, "done"), "its automatic fit is done")

    # ---- the request's checks ----
    url = "/api/scans/%d/fits" % scan
    c.error(d.post(url, {"pixels": "some"}), 422, "pixels", "pixels other than \"all\": 422")
    c.error(d.post(url, {"pixels": "all", "dcol": 1}), 422, "dcol", "pixels with dcol: 422")
    c.error(d.post(url, {"pixels": 5}), 400, "pixels", "pixels not a string: 400")

    # ---- coverage ----
    r = d.get("/api/scans/%d/coverage" % scan)
    c.status(r, 200, "coverage of the scan")
    cov = r.json()
    c.eq((cov["covered"], cov["not_covered"]), (25, 24), "25 pixels covered, 24 not")
    px = {(p["dcol"], p["drow"]): p for p in cov["pixels"]}
    c.eq(len(px), SUB * SUB, "every pixel of the sub-frame is listed")
    c.eq({k for k, p in px.items() if p["status"] == "covered"}, COVERED,
         "the covered pixels are the raster's 5 x 5")
    c.ok(all(px[k]["n_inside"] == INSIDE for k in COVERED), "each has 9 x 9 points inside")
    out = [p for k, p in px.items() if k not in COVERED]
    c.ok(all(p["status"] == "not_covered" and p["reason"] and p["fit_id"] is None
             and p["calibration_id"] is None for p in out),
         "the others are not_covered, with a reason, no fit, no calibration")
    c.ok("right edge" in px[(3, 0)]["reason"], "the reason names the edge the raster misses")
    c.eq(px[(0, 0)]["fit_id"], db.val("SELECT fit_id FROM jobs WHERE id = ?", auto),
         "the POI's fit is the automatic fit")

    # ---- cancel mid-way: held after 3 pixels, cancelled ----
    fits0 = db.val("SELECT count(*) FROM fits WHERE scan_id = ?", scan)
    fits0_id = db.val("SELECT max(id) FROM fits")
    r = d.post(url, {"pixels": "all", "r_max": 6})
    c.status(r, 202, "fit every pixel (to cancel)")
    job = r.json()["job"]["id"]
    c.eq(r.json()["job"]["params"].get("pixels"), "all", "the job's params say pixels: all")
    c.ok(d.wait_held("fit.pixel", job), "held after its 3rd pixel")
    c.eq(db.val("SELECT points_done FROM jobs WHERE id = ?", job), 3, "3 pixels done")
    c.eq(db.val("SELECT count(*) FROM fits WHERE scan_id = ?", scan) - fits0, 3, "3 fits stored")
    c.status(d.post("/api/jobs/%d/cancel" % job, {}), 200, "cancel the job")
    c.ok(d.wait_hold_ended("fit.pixel", job), "the hold ends with the cancel")
    c.ok(d.wait_job(job, "cancelled"), "cancelled")
    check_job_fits(c, d, db, job, scan, fits0_id, 3)
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0 (the worker has left the job)")
    c.eq(db.one("SELECT state, points_done FROM jobs WHERE id = ?", job), ("cancelled", 3),
         "the job is cancelled with its 3 pixels")
    c.eq(db.val("SELECT count(*) FROM fits WHERE scan_id = ?", scan) - fits0, 3,
         "the cancelled job stored its 3 pixels and nothing more")
    c.eq(db.val("SELECT count(*) FROM calibrations WHERE scan_id = ?", scan), 1,
         "not promoted: the scan's one calibration is still the automatic fit's")

    # ---- crash after 5 pixels, resume ----
    # held after the 5th pixel first, crashing when released (the 202 comes before the crash)
    d.start("--calibration-map", "recommended", failpoints="fit.pixel=hold@5;fit.pixel=crash@5")
    fits1 = db.val("SELECT max(id) FROM fits")
    r = d.post(url, {"pixels": "all", "r_max": 8, "promote": True, "by": "test"})
    c.status(r, 202, "fit every pixel, promoted (to crash)")
    job = r.json()["job"]["id"]
    c.ok(d.release_when_held("fit.pixel", job), "held after the 5th pixel")
    c.eq(d.wait_exit(), -9, "ipsd crashed after the 5th pixel")
    c.eq(db.one("SELECT state, points_done FROM jobs WHERE id = ?", job), ("running", 5),
         "the job is left running with 5 pixels done")
    c.eq(db.val("SELECT count(*) FROM fits WHERE id > ?", fits1), 5, "5 fits stored")
    c.eq(db.val("SELECT count(*) FROM calibrations WHERE changed_by = 'test'"), 5,
         "5 calibrations stored")
    # the restart holds the job after its first pixel of the new run, so the event stream is
    # subscribed before the rest (the 6th pixel's event may come before it: not checked)
    d.start("--calibration-map", "recommended", failpoints="fit.pixel=hold@1")
    c.ok(d.wait_held("fit.pixel", job), "resumed and held after its 6th pixel")
    c.eq(db.val("SELECT points_done FROM jobs WHERE id = ?", job), 6, "6 pixels done")
    sse = EventStream(d.port, "/api/events?job=%d" % job)
    c.ok(sse.ready, "event stream of the job")
    d.release("fit.pixel", job)
    c.ok(d.wait_job(job, "done"), "the resumed job ends done")
    wait_for(lambda: any(e["state"] == "done" for e in sse.events()))
    ev = sse.events()
    sse.close()
    # (the stream's first event is the job's stored state, without the pixels' total)
    ev = [e for e in ev if e["phase"] in ("fit", "done")]
    done = [e["points_done"] for e in ev if e["state"] == "running"]
    c.ok(done == sorted(done) and set(range(6, 25)) <= set(done),
         "the events count the pixels in order, 6 .. 24 done while running")
    c.ok(all(e["points_total"] == 25 for e in ev if e["state"] == "running"),
         "of 25 pixels in all")
    c.eq(ev[-1]["state"], "done", "the last event is done")
    # each pixel's events name it: while fitting (fit_id null), and once stored (its fit_id)
    where = dict(db.all("SELECT id, dcol || ',' || drow FROM fits WHERE id > ?", fits1))
    run = [e for e in ev if e["phase"] == "fit" and e["state"] in ("running", "done")]
    c.ok(all("pixel" in e for e in run), "every pixel event carries its pixel")
    stored = [e for e in run if e["fit_id"] is not None and "pixel" in e]
    c.ok(len(stored) >= 19 and all(
        where.get(e["fit_id"]) == "%d,%d" % (e["pixel"]["dcol"], e["pixel"]["drow"])
        and (e["pixel"]["col"], e["pixel"]["row"]) == (40 + e["pixel"]["dcol"],
                                                       50 + e["pixel"]["drow"])
        for e in stored), "a stored pixel's event names the pixel of its fit (%d)" % len(stored))
    c.eq(db.one("SELECT points_done, attempts FROM jobs WHERE id = ?", job), (25, 2),
         "25 pixels done in two runs")
    rows = db.all("SELECT dcol, drow FROM fits WHERE id > ?", fits1)
    c.eq(len(rows), 25, "25 fits for the job: none twice")
    c.eq(set(rows), COVERED, "one fit of every covered pixel")
    check_job_fits(c, d, db, job, scan, fits1, 25)
    cal = db.all("SELECT pixel_col - 40, pixel_row - 50, fit_id FROM calibrations "
                 "WHERE changed_by = 'test' AND superseded_by IS NULL")
    c.eq(len(cal), 25, "25 current calibrations by the request")
    c.eq({(a, b) for a, b, _ in cal}, COVERED, "one of every covered pixel")
    c.eq(db.val("SELECT count(*) FROM calibrations WHERE changed_by = 'test'"), 25,
         "and no calibration twice")

    # ---- the maps against the simulator's truth ----
    worst, zmax, errs = 0, 0, []
    for dc, dr in sorted(COVERED):
        r = d.get("/api/sensors/%d/pixels/%d/%d/calibration" % (sensor, 40 + dc, 50 + dr))
        c.status(r, 200, "calibration of pixel (%+d, %+d)" % (dc, dr))
        m = r.json()
        T = truth[m["r"]]
        bad = [i for i, (s, e, tv) in enumerate(zip(m["S"], m["S_err"], T))
               if abs(s - tv) > K_SIGMA * e + MODEL]
        worst = max([worst] + [abs(s - tv) for s, tv in zip(m["S"], T)])
        zmax = max([zmax] + [abs(s - tv) / e for s, e, tv in zip(m["S"], m["S_err"], T)])
        errs += m["S_err"]
        c.ok(not bad, "pixel (%+d, %+d) r = %d matches the truth (%d sub-pixels off)"
             % (dc, dr, m["r"], len(bad)))
    print("largest |S - truth| over the 25 maps: %.4f, largest |S - truth| / S_err: %.1f, "
          "median S_err %.4f" % (worst, zmax, sorted(errs)[len(errs) // 2]))
    r = d.get("/api/scans/%d/coverage" % scan)
    cov = {(p["dcol"], p["drow"]): p for p in r.json()["pixels"]}
    c.ok(all(cov[k]["fit_id"] and cov[k]["calibration_id"] for k in COVERED),
         "coverage names each covered pixel's fit and calibration")
    c.ok(all(cov[k]["fit_id"] is None and cov[k]["calibration_id"] is None
             for k in cov if k not in COVERED), "and none for the others")
    db.close()
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
