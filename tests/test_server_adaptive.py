#!/usr/bin/env python3
"""test_server_adaptive.py IPSD IPS: adaptive scans (POST /api/scans "strategy": {"kind":
"adaptive"}) on the simulated bench.

- Bad strategies are refused with 4xx naming the field, and nothing is queued.
- An adaptive scan killed after 30 points (held, then crashed at scan.point: mid-way through its
  first batch) resumes at the restart and ends with exactly the positions and values of the same
  scan run uninterrupted afterwards (the planner plans from the stored points only; the simulated
  bench draws each point's noise from the scan's seed and the point's index).
- Read back from the database with Python's own reader: every point stored once, in the order
  taken; the first 25 are the 5 x 5 cell centres of the pixel (computed here), the rest lie inside
  the pixel and off that raster; the count is the stop reason's (the budget, or an expected error
  at or under the target); points_total is the points taken.
- The map: the stored points fitted by `ips fit --sigma shot+read` (another program, the map the
  planner scores) is compared with the simulator's truth (`ips simulate --truth`), as are `ips
  simulate --adaptive` with the same seed and options (the CLI reads the POI alone from one noise
  stream where ipsd reads its sub-frame from a stream per point, so their values and then their
  positions differ; it must stop at as many points) and a 7 x 7 raster of the same 49 points:
  the adaptive scan's rms error against the truth is within 1.5x of each (measured: 0.040
  against 0.038 and 0.039).
- Progress events of the scan carry phase "adaptive" and the expected error.
- A cancel (the scan held after 10 points) ends the scan and keeps its points.
- A target met after the first batch (the lowest expected error after the first plan of the same
  scan run with no target, read from its events), the scan killed after 30 points: it resumes
  and stops on the target at the first plan that meets it, where the same scan uninterrupted
  stops, with the same points.
- The scan list (GET /api/scans) says how each scan takes its points: the strategy as requested
  with the defaults of docs/api.md filled in (target_err 0.01, max_points 300, batch 9,
  start_grid 5), {"kind": "raster"} for a raster scan, also when the request named none; the
  same as each scan's own GET.
"""
import json
import math
import os
import struct
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, EventStream, Ipsd

SEED, POI = 7, {"col": 128, "row": 128}
STRATEGY = {"kind": "adaptive", "target_err": 0.01, "max_points": 49, "batch": 9,
            "start_grid": 5}
SUB = 3
FACTOR = 1.5  # the adaptive map's error against the truth, at most this times the others'


def scan_request(sensor):
    return {"sensor_id": sensor, "poi": POI, "setup": "none", "seed": SEED,
            "raster": {"sub_px": SUB}, "strategy": STRATEGY}


def points(db, scan):
    """(point_index, x, y, POI mean) of every stored point, positions relative to the POI's
    corner from the stored setup's centre, the mean from the stored mean frame's centre."""
    setup = json.loads(db.val("SELECT setup FROM scans WHERE id = ?", scan))
    cx, cy, _ = setup["centre_um"]
    p = setup["pitch_um"]
    sub = db.val("SELECT sub_px FROM scans WHERE id = ?", scan)
    out = []
    for idx, sx, sy, blob in db.all("SELECT point_index, stage_x_um, stage_y_um, mean FROM "
                                    "frames WHERE scan_id = ? ORDER BY point_index", scan):
        mean = struct.unpack("<%dd" % (sub * sub), blob)
        out.append((idx, sx - (cx - p / 2), sy - (cy - p / 2), mean[(sub // 2) * sub + sub // 2]))
    return out, setup


def scan_file(setup, pts, path):
    """The stored points as a scan file (docs/contracts.md) for `ips fit`."""
    doc = {k: setup[k] for k in ("pitch_um", "spot_radius_um", "bias_dn", "gain_e_per_dn",
                                 "read_noise_e", "full_scale_dn")}
    doc.update(frames=12, x_um=[q[1] for q in pts], y_um=[q[2] for q in pts],
               signal_dn=[q[3] for q in pts])
    with open(path, "w") as f:
        json.dump(doc, f)


def kriged(ips, path):
    out = subprocess.run([ips, "fit", "--sigma", "shot+read", path], capture_output=True,
                         text=True, timeout=ipsd_http.DEADLINE_S * 4)
    if out.returncode != 0:
        raise RuntimeError("ips fit %s: %s" % (path, out.stderr))
    k = json.loads(out.stdout)["kriged_map"]
    return k["S"], k["grid"]


def rms_truth(S, grid, truth, n=120):
    """The rms difference of the map and the truth's finest sub-pixel means (r = 10), both
    sampled at n x n points over the pixel and normalised to mean 1 there."""
    t = truth["maps"][-1]
    tr, T = t["r"], t["S_normalised"]
    a = [S[int((j + 0.5) / n * grid) * grid + int((i + 0.5) / n * grid)]
         for j in range(n) for i in range(n)]
    b = [T[int((j + 0.5) / n * tr) * tr + int((i + 0.5) / n * tr)]
         for j in range(n) for i in range(n)]
    ma, mb = sum(a) / len(a), sum(b) / len(b)
    return math.sqrt(sum((x / ma - y / mb) ** 2 for x, y in zip(a, b)) / len(a))


def check_refusals(c, d, db, sensor):
    base = {"sensor_id": sensor, "poi": POI}
    before = db.one("SELECT (SELECT count(*) FROM scans), (SELECT count(*) FROM jobs)")
    bad = [
        ({"kind": "spiral"}, 422, "strategy.kind"),
        ({}, 422, "strategy.kind"),
        ({"kind": 3}, 400, "strategy.kind"),
        ("adaptive", 400, "strategy"),
        ({"kind": "adaptive", "target_err": 0}, 422, "strategy.target_err"),
        ({"kind": "adaptive", "target_err": -0.01}, 422, "strategy.target_err"),
        ({"kind": "adaptive", "target_err": "small"}, 400, "strategy.target_err"),
        ({"kind": "adaptive", "max_points": 24}, 422, "strategy.max_points"),
        ({"kind": "adaptive", "start_grid": 7, "max_points": 48}, 422, "strategy.max_points"),
        ({"kind": "adaptive", "batch": 0}, 422, "strategy.batch"),
        ({"kind": "adaptive", "batch": 100000}, 422, "strategy.batch"),
        ({"kind": "adaptive", "start_grid": 1}, 422, "strategy.start_grid"),
        ({"kind": "adaptive", "batch": 2.5}, 400, "strategy.batch"),
        ({"kind": "adaptive", "bach": 9}, 422, "strategy.bach"),
        ({"kind": "raster", "batch": 9}, 422, "strategy.batch"),
    ]
    for strategy, status, field in bad:
        r = d.post("/api/scans", dict(base, strategy=strategy))
        c.error(r, status, field, "strategy %r refused" % (strategy,))
    # a target that is not a finite number cannot be written in JSON: 1e999 is refused as such
    r = d.post("/api/scans", dict(base, strategy={"kind": "adaptive", "target_err": 1e999}))
    c.ok(400 <= r.status < 500, "target_err 1e999 refused (%d)" % r.status)
    c.eq(db.one("SELECT (SELECT count(*) FROM scans), (SELECT count(*) FROM jobs)"), before,
         "nothing queued by the refused requests")


def check_list(c, d, sensor, s1, s2, s3):
    """Queued behind the held scan s3 (one scan worker), an adaptive scan with every member left
    to its default, a raster scan naming its strategy and one naming none, all cancelled while
    queued; then the list's strategies."""
    req = {"sensor_id": sensor, "poi": {"col": 90, "row": 90}, "raster": {"sub_px": SUB}}
    s4 = d.post("/api/scans", dict(req, strategy={"kind": "adaptive"})).json()["scan"]["id"]
    s5 = d.post("/api/scans", dict(req, strategy={"kind": "raster"})).json()["scan"]["id"]
    s6 = d.post("/api/scans", req).json()["scan"]["id"]
    for s in (s4, s5, s6):
        c.status(d.post("/api/scans/%d/cancel" % s), 200, "queued scan %d cancelled" % s)
    defaults = {"kind": "adaptive", "target_err": 0.01, "max_points": 300, "batch": 9,
                "start_grid": 5}
    want = {s1: STRATEGY, s2: STRATEGY, s3: STRATEGY, s4: defaults, s5: {"kind": "raster"},
            s6: {"kind": "raster"}}
    page = d.get("/api/scans?limit=1000").json()
    got = {i["id"]: i.get("strategy") for i in page["items"]}
    c.eq(got, want, "the list's strategies: as requested, defaults filled in")
    for s in want:
        c.eq(d.get("/api/scans/%d" % s).json()["strategy"], want[s], "scan %d's GET agrees" % s)
    paged = d.get("/api/scans?limit=2&offset=1&state=cancelled").json()["items"]
    c.eq([(i["id"], i["strategy"]) for i in paged], [(s5, want[s5]), (s4, want[s4])],
         "a filtered page carries its own scans' strategies")


def test(c, t, argv, daemons):
    ips = argv[2]
    d = Ipsd(argv[1], t)
    daemons.append(d)
    # ---- killed mid-way through the first batch: after 25 + 5 points ----
    d.start(failpoints="scan.point=hold@30;scan.point=crash@30")
    db = Db(d.db)
    sensor = d.post("/api/sensors", {"model": "IMX-A", "serial": "adaptive-1"}).json()["id"]
    check_refusals(c, d, db, sensor)
    r = d.post("/api/scans", scan_request(sensor))
    c.status(r, 202, "adaptive scan queued")
    body = r.json()
    s1, j1 = body["scan"]["id"], body["job"]["id"]
    c.eq(body["scan"]["strategy"], STRATEGY, "the reply's strategy")
    c.eq(body["scan"]["raster"]["points_total"], 49, "points_total is the budget while it runs")
    c.ok(d.wait_held("scan.point", j1), "held after 30 points")
    c.eq(db.val("SELECT count(*) FROM frames WHERE scan_id = ?", s1), 30, "30 points stored")
    d.release("scan.point", j1)  # the crash follows the hold
    d.wait_exit()
    c.eq(db.val("SELECT state FROM jobs WHERE id = ?", j1), "running", "left running by the crash")

    d.start()
    c.ok(d.wait_job(j1, "done"), "the resumed scan is done")
    # ---- the same scan, uninterrupted, watched by an event stream ----
    ev = EventStream(d.port)
    r = d.post("/api/scans", scan_request(sensor))
    s2, j2 = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_job(j2, "done"), "the uninterrupted scan is done")
    c.ok(ipsd_http.wait_for(lambda: any(e["id"] == j2 and e["state"] == "done"
                                        for e in ev.events())), "its done event")
    evs = [e for e in ev.events() if e["id"] == j2 and e.get("phase") == "adaptive"]
    ev.close()
    c.ok(len(evs) >= 49, "a progress event a point at least (%d)" % len(evs))
    errs = [e["expected_err"] for e in evs if "expected_err" in e]
    c.ok(len(errs) >= 3 and all(0 < x < 1 for x in errs),
         "events carry the expected error of each plan (%s)" % errs[:6])

    p1, setup1 = points(db, s1)
    p2, setup2 = points(db, s2)
    c.eq([q[0] for q in p1], list(range(49)), "the resumed scan: indices 0..48, each once")
    c.eq(db.val("SELECT count(*) FROM frames WHERE scan_id = ?", s1), 49,
         "the resumed scan: 49 rows")
    c.eq([q[:3] for q in p1], [q[:3] for q in p2], "the resumed scan took the positions of the "
         "uninterrupted one")
    c.eq([q[3] for q in p1], [q[3] for q in p2], "and read the same values")
    c.eq(db.val("SELECT attempts FROM jobs WHERE id = ?", j1), 2, "claimed twice")

    # what the scans are, read back
    g = d.get("/api/scans/%d" % s2).json()
    c.eq(g["strategy"], STRATEGY, "GET returns the strategy")
    a = g["setup"]["adaptive"]
    c.eq(db.one("SELECT points_total, points_done, state FROM scans WHERE id = ?", s2),
         (len(p2), len(p2), "done"), "points_total is the points taken")
    if a["stop"] == "budget":
        c.eq(len(p2), STRATEGY["max_points"], "stopped at the budget: max_points points")
    else:
        c.ok(a["stop"] == "target" and a["expected_err"] <= STRATEGY["target_err"],
             "stopped at the target: %r" % a)
    c.eq(a["points"], len(p2), "the stop's count is the rows'")
    start = [(0.6 + 1.2 * i, 0.6 + 1.2 * j) for j in range(5)
             for i in (range(5) if j % 2 == 0 else range(4, -1, -1))]
    c.ok(all(abs(q[1] - x) < 1e-9 and abs(q[2] - y) < 1e-9 for q, (x, y) in zip(p2, start)),
         "the first 25 points are the 5 x 5 cell centres, row by row, each row the other way")
    rest = p2[25:]
    c.ok(all(0 < q[1] < 6 and 0 < q[2] < 6 for q in rest), "the batches' points lie inside")
    off = [q for q in rest if min(abs(q[1] - x) + abs(q[2] - y) for x, y in start) > 1e-6]
    c.ok(len(off) >= len(rest) // 2, "the batches go elsewhere than the starting raster (%d of "
         "%d)" % (len(off), len(rest)))
    c.ok(len({(round(q[1], 9), round(q[2], 9)) for q in rest}) > 1, "and not to one place")
    c.eq(d.get("/api/scans?limit=1").json()["total"], 2, "two scans stored")

    # the automatic fits run as for a raster
    for scan in (s1, s2):
        items = d.get("/api/jobs?kind=fit&scan=%d" % scan).json()["items"]
        c.ok(len(items) == 1 and d.wait_job(items[0]["id"], "done"),
             "scan %d's automatic fit done" % scan)
    c.eq(db.val("SELECT count(*) FROM calibrations WHERE superseded_by IS NULL"), 1,
         "one current calibration of the POI")

    # ---- the map against the simulator's truth, beside the CLI's adaptive scan and a raster ----
    scan_file(setup2, p2, os.path.join(t, "ipsd.json"))
    run = lambda *a: subprocess.run([ips, "simulate", "--seed", str(SEED), *a], check=True,
                                    capture_output=True, timeout=ipsd_http.DEADLINE_S * 4)
    run("--adaptive", "--max-points", "49", "--batch", "9", "--start-grid", "5",
        "--target-err", "0.01", "--truth", os.path.join(t, "truth.json"), "-o",
        os.path.join(t, "cli.json"))
    run("--grid", "7", "--step", repr(6 / 7), "-o", os.path.join(t, "raster.json"))
    with open(os.path.join(t, "truth.json")) as f:
        truth = json.load(f)
    with open(os.path.join(t, "cli.json")) as f:
        cli_n = len(json.load(f)["x_um"])
    c.eq(cli_n, len(p2), "ips simulate --adaptive with the same options stops at as many points")
    e_ipsd = rms_truth(*kriged(ips, os.path.join(t, "ipsd.json")), truth)
    e_cli = rms_truth(*kriged(ips, os.path.join(t, "cli.json")), truth)
    e_raster = rms_truth(*kriged(ips, os.path.join(t, "raster.json")), truth)
    print("rms against the truth: ipsd adaptive %.4f, ips simulate --adaptive %.4f, 7 x 7 raster "
          "%.4f; ipsd's expected error %.4f" % (e_ipsd, e_cli, e_raster, a["expected_err"]))
    c.ok(e_ipsd <= FACTOR * e_cli, "within %.1fx of the CLI's adaptive scan" % FACTOR)
    c.ok(e_ipsd <= FACTOR * e_raster, "within %.1fx of the 7 x 7 raster" % FACTOR)
    c.eq(d.stop_term(), 0, "ipsd stops cleanly")

    # ---- a cancel mid-scan keeps what is stored ----
    d.start(failpoints="scan.point=hold@10")
    r = d.post("/api/scans", dict(scan_request(sensor), poi={"col": 100, "row": 100}))
    s3, j3 = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_held("scan.point", j3), "the third scan held after 10 points")
    kept = points(db, s3)[0]
    check_list(c, d, sensor, s1, s2, s3)
    r = d.post("/api/scans/%d/cancel" % s3)
    c.status(r, 200, "cancelled")
    c.ok(d.wait_job(j3, "cancelled"), "its job cancelled")
    c.ok(d.wait_hold_ended("scan.point", j3), "the hold ended by the cancel")
    c.eq(db.one("SELECT state, points_done FROM scans WHERE id = ?", s3), ("cancelled", 10),
         "the scan cancelled with its 10 points")
    c.eq(points(db, s3)[0], kept, "the points stored before the cancel are kept")
    c.eq(d.get("/api/scans/%d" % s3).json()["strategy"], STRATEGY, "and its strategy")
    c.eq(d.stop_term(), 0, "ipsd stops cleanly")
    check_target_resume(c, d, db, sensor)
    db.close()


def check_target_resume(c, d, db, sensor):
    """A target the map reaches after its first batch: the same scan with no target, watched by
    an event stream, gives each plan's expected error, and the target is the lowest after the
    first plan (so the first plan misses it). Killed mid-way through its first batch, the scan
    resumes, replays its plans and stops on the target where the same scan run uninterrupted
    does, with the same points, at the first plan whose expected error is at or under it."""
    poi = {"col": 110, "row": 110}
    d.start()
    ev = EventStream(d.port)
    r = d.post("/api/scans", dict(scan_request(sensor), poi=poi,
                                  strategy=dict(STRATEGY, target_err=1e-6)))
    j = r.json()["job"]["id"]
    c.ok(d.wait_job(j, "done"), "the probe scan with no target is done")
    c.ok(ipsd_http.wait_for(lambda: any(e["id"] == j and e["state"] == "done"
                                        for e in ev.events())), "its done event")
    plans = []  # each plan's expected error, once (every point's event repeats the last plan's)
    for e in ev.events():
        if e["id"] == j and "expected_err" in e and (not plans or plans[-1] != e["expected_err"]):
            plans.append(e["expected_err"])
    ev.close()
    d.stop_term()
    target = min(plans[1:])
    c.ok(len(plans) >= 3 and target < plans[0],
         "the probe's plans: %s; the target %.5f is met after the first" % (plans, target))
    first = min(25 + 9 * next(k for k, e in enumerate(plans) if e <= target), 49)
    req = dict(scan_request(sensor), poi=poi, strategy=dict(STRATEGY, target_err=target))
    d.start(failpoints="scan.point=hold@30;scan.point=crash@30")
    r = d.post("/api/scans", req)
    s4, j4 = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_held("scan.point", j4), "the loose-target scan held after 30 points")
    d.release("scan.point", j4)
    d.wait_exit()
    d.start()
    c.ok(d.wait_job(j4, "done"), "the resumed loose-target scan is done")
    r = d.post("/api/scans", req)
    s5, j5 = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_job(j5, "done"), "the uninterrupted loose-target scan is done")
    p4, setup4 = points(db, s4)
    p5, setup5 = points(db, s5)
    a4, a5 = setup4["adaptive"], setup5["adaptive"]
    print("target %.5f: the resumed scan stopped (%s) at %d points, expected error %.5f"
          % (target, a4["stop"], len(p4), a4["expected_err"]))
    c.ok(a4["stop"] == "target" and a4["expected_err"] <= target and len(p4) == first,
         "stopped on the target at the first plan that met it (%d points): %r, %d points"
         % (first, a4, len(p4)))
    c.eq((a4["stop"], a4["points"], len(p4)), (a5["stop"], a5["points"], len(p5)),
         "the resumed scan stopped where the uninterrupted one did")
    c.eq(p4, p5, "with the same positions and values")
    c.eq(d.stop_term(), 0, "ipsd stops cleanly")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
