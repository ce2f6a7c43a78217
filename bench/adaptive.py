#!/usr/bin/env python3
"""adaptive.py [BUILD_DIR] [--quick] [--scenes A,B] [--seeds N] [--light F,G] [--max-points N]
[--start-grid N] [--batch B] [--json FILE] [--from FILE]: how many points, and how much bench time, an adaptive scan (`ips
simulate --adaptive`, fit/adapt_plan.h) needs to reach the kriged map's error that the paper's
rasters reach, on the simulated bench against its truth; prints figures (never pass/fail).

Per scene family (each with 10 x 10 cells, so that `--truth` holds the scene itself), light level
(a fraction of `ips simulate`'s default --peak-e) and seed:
- the references: the 9 x 9 raster at 0.6 um (`--grid 9`, the paper's) and the 13 x 13 raster at
  0.42 um (the fidelity harness's, bench/fidelity.c: 5.04 um across against 4.8, the same pixel
  3/2 as densely), each fitted by `ips fit --sigma shot+read`: its kriged map's rms against the
  truth (e, the scene's own 10 x 10 cells, sampled as the fidelity harness samples) and its
  expected error (the rms of its S_err, E);
- one adaptive scan (5 x 5 start, batches of 9, or --start-grid N, --batch B; no target, up
  to --max-points): after each batch
  the summary gives the refitted map's expected error and its rms against the truth (the map `ips
  fit` gives of the same points), its recommended r and whether the map kept its smooth part.
  Per reference: the points at the first batch whose measured rms is <= e (n_meas: what an oracle
  would stop at) and where the scan itself would stop with the reference's error bar E as its
  target (n_exp: fit/adapt_plan.h's stop, from what the summary's batches say: the first batch
  after the starting raster whose expected error is <= E; both E and the batches' expected
  error are the kriged map's under the neighbouring priors, `ips fit --krige-mixture`), the
  measured rms at n_exp, and the adaptive map's rms at the reference's point count
  (the last batch not past it); the ratio of measured to expected error over every batch;
- the smallest n x n raster of cell centres (n = 4..9, `--grid n --step 6/n`) as good as e9;
- bench time, modelled from the positions in the order the scan file holds them, starting at the
  pixel's centre: per point one move (settling plus distance over the stage speed) and `frames`
  exposures each followed by the read-out. The constants are the simulated bench's defaults
  (below); frames and exposure are the scan's own (scan file, simulate summary). The adaptive
  scan's planning (the summary's plan_ms, this machine's CPU) is reported beside it, not in it.

Defaults: the twelve families, light 1 and 0.1, seeds 1-5, 250 points (7-13 minutes on one
core); --quick: dip, gradient and softedge, seed 1, 180 points (15-30 s). Medians over seeds (a scan
that never reaches the error counts as more than any that does), each seed in brackets; errors
below 1e-9 (the uniform scene's exact maps) are "exact". The raw results go to --json FILE, and
--from FILE prints the tables again.
"""
import json
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from fitdoc import rms_vs_truth  # noqa: E402

# The simulated bench's defaults (bench time model).
SPEED_UM_S = 1000.0  # stage_sim_config_default: speed_um_s (instrument/stage.h)
SETTLE_S = 0.05  # stage_sim_config_default: settle_s (instrument/stage.h)
READOUT_S = 0.02  # sim_config_default: readout_s, per frame (instrument/sim.h)

FAMILIES = ["uniform", "paperlike", "gradient", "dip", "deadcorner", "edge", "softedge", "ring",
            "busline", "diagedge", "bowl", "twodips"]
REFS = ((9, 0.6), (13, 0.42))
# Errors below this are rounding (the uniform scene's maps are exact to ~1e-14): compared with
# this slack, and no ratio is taken of them.
TOL = 1e-9


def bench_s(x, y, pitch, frames, exposure_us):
    """Moves (settling + path / speed) and exposures (frames x (exposure + read-out)) of a scan
    visiting (x, y) in order from the pixel's centre."""
    px = py = pitch / 2
    path = 0.0
    for a, b in zip(x, y):
        path += math.hypot(a - px, b - py)
        px, py = a, b
    n = len(x)
    return {"move_s": n * SETTLE_S + path / SPEED_UM_S,
            "expose_s": n * frames * (exposure_us * 1e-6 + READOUT_S),
            "path_um": path}


def total(t):
    return t["move_s"] + t["expose_s"]


def measure(ips, scene, light, seed, max_points, peak_default, tmp, plan=(5, 9)):
    truth, grid, adapt = (os.path.join(tmp, n) for n in ("t.json", "g.json", "a.json"))

    def run(*a):
        return subprocess.run([ips, *a], capture_output=True, text=True, check=True).stdout

    # uniform takes no cell count: it is 1 everywhere, which its r = 10 truth holds as well
    common = ["--scene", scene if scene == "uniform" else scene + ":10", "--seed", str(seed),
              "--truth", truth]
    if light != 1:
        common += ["--peak-e", repr(peak_default * light)]

    def scan(*opts):
        summary = json.loads(run("simulate", *common, *opts))
        with open(opts[opts.index("-o") + 1]) as f:
            sf = json.load(f)
        return summary, sf

    rec = {"scene": scene, "light": light, "seed": seed}
    for n, step in REFS:
        summary, sf = scan("--grid", str(n), "--step", repr(step), "-o", grid)
        kr = json.loads(run("fit", grid, "--sigma", "shot+read", "--krige-mixture"))["kriged_map"]
        with open(truth) as f:
            t = [m for m in json.load(f)["maps"] if m["r"] == 10][0]
        rec["e%d" % n] = rms_vs_truth(kr["S"], kr["grid"], t["S"], 10)
        # the expected error as the adaptive scan reports it (under the neighbouring priors), and
        # the posterior's alone
        rec["E%d" % n] = kr["mixture"]["expected_err"]
        rec["P%d" % n] = (sum(e * e for e in kr["S_err"]) / len(kr["S_err"])) ** 0.5
        rec["t%d" % n] = bench_s(sf["x_um"], sf["y_um"], sf["pitch_um"], sf["frames"],
                                 summary["setup"]["exposure_us"])
    summary, sf = scan("--adaptive", "--target-err", "1e-6", "--max-points", str(max_points),
                       "--start-grid", str(plan[0]), "--batch", str(plan[1]), "-o", adapt)
    bs = summary["adaptive"]["batches"]
    exp_us = summary["setup"]["exposure_us"]
    rec["batches"] = [{"points": b["points"], "expected": b["expected_err"],
                       "posterior": b["posterior_err"],
                       "measured": b["rms_err_truth"], "plan_ms": b["plan_ms"],
                       "r": b["r"], "smooth": b["smooth"],
                       **bench_s(sf["x_um"][:b["points"]], sf["y_um"][:b["points"]],
                                 sf["pitch_um"], sf["frames"], exp_us)} for b in bs]
    rec["cells"] = None  # the smallest n x n raster of cell centres as good as e9
    for n in range(4, 10):
        run("simulate", *common, "--grid", str(n), "--step", repr(6.0 / n), "-o", grid)
        kr = json.loads(run("fit", grid, "--sigma", "shot+read"))["kriged_map"]
        if rms_vs_truth(kr["S"], kr["grid"], t["S"], 10) <= rec["e9"]:
            rec["cells"] = n * n
            break
    return rec


def reached(b, target):
    """fit/adapt_plan.h's stop at batch b on target: its expected error at or below it."""
    return b["expected"] <= target + TOL


def derive(rec, n):
    """Per reference n x n: n_meas, n_exp (None: never), the rms at n_exp, the rms at n points,
    bench and planning seconds at n_meas and n_exp."""
    bs = rec["batches"]
    e, E = rec["e%d" % n], rec["E%d" % n]
    bm = next((b for b in bs if b["measured"] <= e + TOL), None)
    be = next((b for b in bs[1:] if reached(b, E)), None)

    def plan_s(b):
        return sum(c["plan_ms"] for c in bs if c["points"] <= b["points"]) / 1000 if b else None

    at = [b for b in bs if b["points"] <= n * n][-1]
    return {"n_meas": bm["points"] if bm else None, "n_exp": be["points"] if be else None,
            "rms_at_exp": be["measured"] if be else None, "rms_at_n": at["measured"],
            "at_n": at["points"],
            "t_meas": total(bm) if bm else None, "t_exp": total(be) if be else None,
            "plan_meas": plan_s(bm), "plan_exp": plan_s(be)}


def med(v):
    """Median, None (never reached) above every number; None if the median is one."""
    v = sorted(v, key=lambda x: math.inf if x is None else x)
    k = [math.inf if x is None else x for x in v]
    m = statistics.median(k)
    return None if m == math.inf else m


def ratios_of(rs):
    """measured / expected of every batch whose map is not exact."""
    return [b["measured"] / b["expected"] for r in rs for b in r["batches"] if b["measured"] > TOL]


def ratio(a, b):
    return None if a is None else a / b


def fmt(x, f="%.0f"):
    return "never" if x is None else f % x


def seeds_of(v):
    return "[" + ", ".join("-" if x is None else "%g" % x for x in v) + "]"


def tables(recs, max_points, plan=(5, 9)):
    groups = {}
    for r in recs:
        groups.setdefault((r["scene"], r["light"]), []).append(r)
    out = []
    for n, _ in REFS:
        N = n * n
        out.append("\n### Against the %d x %d raster (%d points)\n" % (n, n, N))
        out.append("| scene | light | e%d (E%d) | n_meas: rms <= e | n_exp: the scan's stop on E | "
                   "rms at n_exp / e | adaptive rms at %d / e | bench s: raster, adaptive at "
                   "n_meas, at n_exp (+ planning) |" % (n, n, N - (N - plan[0] ** 2) % plan[1]))
        out.append("|---|---|---|---|---|---|---|---|")
        for (scene, light), rs in groups.items():
            d = [derive(r, n) for r in rs]
            e = med([r["e%d" % n] for r in rs])
            exact = e < TOL
            out.append("| %s | %g | %.4f (%.4f) | %s %s | %s %s | %s | %s | %.1f, %s, %s (+%s) |"
                       % (scene, light, e, med([r["E%d" % n] for r in rs]),
                          fmt(med([x["n_meas"] for x in d])), seeds_of([x["n_meas"] for x in d]),
                          fmt(med([x["n_exp"] for x in d])), seeds_of([x["n_exp"] for x in d]),
                          "exact" if exact else fmt(med([ratio(x["rms_at_exp"], r["e%d" % n])
                                                         for x, r in zip(d, rs)]), "%.2f"),
                          "exact" if exact else "%.2f" % med([x["rms_at_n"] / r["e%d" % n]
                                                              for x, r in zip(d, rs)]),
                          med([total(r["t%d" % n]) for r in rs]),
                          fmt(med([x["t_meas"] for x in d]), "%.1f"),
                          fmt(med([x["t_exp"] for x in d]), "%.1f"),
                          fmt(med([x["plan_exp"] for x in d]), "%.1f")))
    out.append("\n### Expected against measured error\n")
    out.append("| scene | light | raster e9 / E9 | raster e13 / E13 | adaptive measured / expected: "
               "median (range) | batches within 1.5x | cell-centre raster as good as e9 |")
    out.append("|---|---|---|---|---|---|---|")
    for (scene, light), rs in groups.items():
        ratios = ratios_of(rs)
        within = sum(1 / 1.5 <= q <= 1.5 for q in ratios)
        if med([r["e9"] for r in rs]) < TOL:
            out.append("| %s | %g | exact | exact | exact (%d batches) | - | %s %s |"
                       % (scene, light, sum(len(r["batches"]) for r in rs),
                          fmt(med([r["cells"] for r in rs])), seeds_of([r["cells"] for r in rs])))
            continue
        out.append("| %s | %g | %.2f | %.2f | %.2f (%.2f-%.2f) | %d of %d | %s %s |"
                   % (scene, light, med([r["e9"] / r["E9"] for r in rs]),
                      med([r["e13"] / r["E13"] for r in rs]), statistics.median(ratios),
                      min(ratios), max(ratios), within, len(ratios),
                      fmt(med([r["cells"] for r in rs])), seeds_of([r["cells"] for r in rs])))
    out.append("\n### Summary over the families (medians per family, then over families)\n")
    out.append("| reference | light | points: n_meas / raster | n_exp / raster | bench time: at "
               "n_meas / raster | at n_exp / raster | families with n_meas <= 1/3, <= 2/3 | "
               "n_exp <= 1/3, <= 2/3 | batches within 1.5x | stops above 1.5x the raster's "
               "error (worst) |")
    out.append("|---|---|---|---|---|---|---|---|---|---|")
    for n, _ in REFS:
        N = n * n
        for light in sorted({r["light"] for r in recs}, reverse=True):
            fm, fe, tm, te, ratios, at_stop = [], [], [], [], [], []
            for (scene, lt), rs in groups.items():
                if lt != light:
                    continue
                d = [derive(r, n) for r in rs]
                fm.append(med([x["n_meas"] / N if x["n_meas"] else None for x in d]))
                fe.append(med([x["n_exp"] / N if x["n_exp"] else None for x in d]))
                tm.append(med([x["t_meas"] / total(r["t%d" % n]) if x["t_meas"] else None
                               for x, r in zip(d, rs)]))
                te.append(med([x["t_exp"] / total(r["t%d" % n]) if x["t_exp"] else None
                               for x, r in zip(d, rs)]))
                ratios += ratios_of(rs)
                at_stop += [x["rms_at_exp"] / r["e%d" % n] for x, r in zip(d, rs)
                            if x["n_exp"] and r["e%d" % n] > TOL]

            def count(v, lim):
                return sum(x is not None and x <= lim for x in v)

            out.append("| %d x %d | %g | %s (%s-%s) | %s (%s-%s) | %s | %s | %d, %d of %d | "
                       "%d, %d of %d | %d of %d | %d of %d (%.2f) |"
                       % (n, n, light, fmt(med(fm), "%.2f"), fmt(min(fm, key=_k), "%.2f"),
                          fmt(max(fm, key=_k), "%.2f"), fmt(med(fe), "%.2f"),
                          fmt(min(fe, key=_k), "%.2f"), fmt(max(fe, key=_k), "%.2f"),
                          fmt(med(tm), "%.2f"), fmt(med(te), "%.2f"),
                          count(fm, 1 / 3), count(fm, 2 / 3), len(fm),
                          count(fe, 1 / 3), count(fe, 2 / 3), len(fe),
                          sum(1 / 1.5 <= q <= 1.5 for q in ratios), len(ratios),
                          sum(q > 1.5 for q in at_stop), len(at_stop), max(at_stop, default=0)))
    out.append("\n(never: not reached within %d points; ranges are over families)" % max_points)
    return "\n".join(out)


def header(doc):
    rs = doc["results"]
    return ("%d scene families x %d light levels x %d seeds, adaptive scans from %d x %d in "
            "batches of %d to %d points; default --peak-e %g; bench model: settling %g s a move, "
            "stage %g um/s, read-out %g s a frame"
            % (len({r["scene"] for r in rs}), len({r["light"] for r in rs}),
               len({r["seed"] for r in rs}), doc.get("start_grid", 5), doc.get("start_grid", 5),
               doc.get("batch", 9), doc["max_points"], doc["peak_e"], SETTLE_S, SPEED_UM_S,
               READOUT_S))


def _k(x):
    return math.inf if x is None else x


def main():
    args = sys.argv[1:]
    build = os.path.join(HERE, "..", "build")
    scenes, seeds, lights, max_points = FAMILIES, 5, [1.0, 0.1], 250
    json_out = json_in = None
    plan = (5, 9)  # the adaptive scan's starting raster (N x N) and batch, ips simulate's defaults
    while args:
        a = args.pop(0)
        if a == "--quick":
            scenes, seeds, lights, max_points = ["dip", "gradient", "softedge"], 1, [1.0, 0.1], 180
        elif a == "--scenes":
            scenes = args.pop(0).split(",")
        elif a == "--seeds":
            seeds = int(args.pop(0))
        elif a == "--light":
            lights = [float(x) for x in args.pop(0).split(",")]
        elif a == "--start-grid":
            plan = (int(args.pop(0)), plan[1])
        elif a == "--batch":
            plan = (plan[0], int(args.pop(0)))
        elif a == "--max-points":
            max_points = int(args.pop(0))
        elif a == "--json":
            json_out = args.pop(0)
        elif a == "--from":
            json_in = args.pop(0)
        else:
            build = a
    if json_in:
        with open(json_in) as f:
            doc = json.load(f)
        print(header(doc))
        print(tables(doc["results"], doc["max_points"],
                     (doc.get("start_grid", 5), doc.get("batch", 9))))
        print("\nran in %.0f s" % doc["seconds"])
        return
    ips = os.path.join(build, "cli", "ips")
    h = subprocess.run([ips, "simulate", "--help"], capture_output=True, text=True)
    helptext = h.stdout + h.stderr
    peak_default = float(re.search(r"--peak-e E.*?\(default ([0-9.e+]+)\)", helptext,
                                   re.S).group(1))
    t0 = time.monotonic()
    recs = []
    with tempfile.TemporaryDirectory() as tmp:
        for scene in scenes:
            for light in lights:
                for seed in range(1, seeds + 1):
                    r = measure(ips, scene, light, seed, max_points, peak_default, tmp, plan)
                    d9, d13 = derive(r, 9), derive(r, 13)
                    print("  %s light %g seed %d: e9 %.4f E9 %.4f n_meas %s n_exp %s; e13 %.4f "
                          "E13 %.4f n_meas %s n_exp %s; cells %s (%.0f s)"
                          % (scene, light, seed, r["e9"], r["E9"], d9["n_meas"], d9["n_exp"],
                             r["e13"], r["E13"], d13["n_meas"], d13["n_exp"], r["cells"],
                             time.monotonic() - t0), file=sys.stderr, flush=True)
                    recs.append(r)
    took = time.monotonic() - t0
    doc = {"max_points": max_points, "start_grid": plan[0], "batch": plan[1], "seconds": took,
           "peak_e": peak_default, "results": recs}
    if json_out:
        with open(json_out, "w") as f:
            json.dump(doc, f)
    print(header(doc))
    print(tables(recs, max_points, plan))
    print("\nran in %.0f s" % took)


if __name__ == "__main__":
    main()
