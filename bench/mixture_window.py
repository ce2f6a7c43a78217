#!/usr/bin/env python3
"""mixture_window.py [BUILD_DIR] [--scenes A,B] [--seeds N] [--light F,G] [--max-points N]
[--jobs J] [--json FILE] [--from FILE]: how honest the kriged map's expected error is, alone and
under the neighbouring priors with each width of Occam's window (`ips fit --krige-mixture`,
fit/krige.h fit_krige_mix), over the batches of adaptive scans on the simulated bench, against
its truth; prints figures (never pass/fail).

Per scene family (10 x 10 cells, so that `--truth` holds the scene itself), light level (a
fraction of `ips simulate`'s default --peak-e) and seed: one adaptive scan with no target (`ips
simulate --adaptive --target-err 1e-6`, up to --max-points), then for the points of every batch
boundary the kriged map of `ips fit --sigma shot+read --krige-mixture`: its rms against the truth
(the measured error, sampled as the fidelity harness samples) and, from its mixture's priors
(r - 1, r, r + 1 with each one's map_err, spread and log_likelihood), the expected error
    e_W^2 = mean over the priors within W of the best log-likelihood of (map_err^2 + spread^2)
for W = 0 (the recommended r's posterior alone: the map's own S_err) and each window below. Per
family and light: the batches whose measured / expected is within 1.5x, and its median.

Defaults: the twelve families but the flat one (whose maps are exact), light 1 and 0.1, seeds
1-5, 160 points, two jobs at once (about 5 minutes on two cores). --json FILE keeps the raw
results, --from FILE prints the tables again.
"""
import argparse
import json
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from fitdoc import rms_vs_truth  # noqa: E402

FAMILIES = ["paperlike", "gradient", "dip", "deadcorner", "edge", "softedge", "ring", "busline",
            "diagedge", "bowl", "twodips"]
WINDOWS = [0, 6.9, 14, 20, 30, 50, math.inf]  # 0: the posterior alone


def one_scan(ips, scene, light, seed, max_points, peak, tmp):
    """Every batch boundary of one adaptive scan: measured error and the mixture's priors."""
    d = os.path.join(tmp, "%s-%g-%d" % (scene, light, seed))
    os.makedirs(d)
    scan, truth, cut = (os.path.join(d, n) for n in ("a.json", "t.json", "c.json"))
    cmd = [ips, "simulate", "--scene", scene + ":10", "--seed", str(seed), "--adaptive",
           "--target-err", "1e-6", "--max-points", str(max_points), "--truth", truth, "-o", scan]
    if light != 1:
        cmd += ["--peak-e", repr(peak * light)]
    summary = json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout)
    with open(scan) as f:
        sf = json.load(f)
    with open(truth) as f:
        t = [m for m in json.load(f)["maps"] if m["r"] == 10][0]
    sf.pop("adaptive", None)
    rows = []
    for b in summary["adaptive"]["batches"]:
        n = b["points"]
        c = dict(sf, **{k: sf[k][:n] for k in ("x_um", "y_um", "signal_dn")})
        with open(cut, "w") as f:
            json.dump(c, f)
        kr = json.loads(subprocess.run([ips, "fit", cut, "--sigma", "shot+read",
                                        "--krige-mixture"], capture_output=True, text=True,
                                       check=True).stdout)["kriged_map"]
        rows.append({"points": n, "r": kr["r"],
                     "measured": rms_vs_truth(kr["S"], kr["grid"], t["S"], 10),
                     "priors": kr["mixture"]["priors"]})
    return {"scene": scene, "light": light, "seed": seed, "batches": rows}


def expected(priors, r, w):
    """The expected error with window w (0: the posterior of the recommended r alone)."""
    if w == 0:
        return next(p["map_err"] for p in priors if p["r"] == r)
    best = max(p["log_likelihood"] for p in priors)
    inside = [p for p in priors if p["log_likelihood"] >= best - w]
    return math.sqrt(sum(p["map_err"] ** 2 + p["spread"] ** 2 for p in inside) / len(inside))


def tables(recs):
    out = ["| scene | light | " + " | ".join("alone" if w == 0 else "W = %g" % w
                                              for w in WINDOWS) + " |",
           "|---|---|" + "---|" * len(WINDOWS)]
    totals = {}
    for light in sorted({r["light"] for r in recs}, reverse=True):
        for scene in [s for s in FAMILIES if any(r["scene"] == s for r in recs)]:
            bs = [b for r in recs if r["scene"] == scene and r["light"] == light
                  for b in r["batches"]]
            cells = []
            for w in WINDOWS:
                q = [b["measured"] / expected(b["priors"], b["r"], w) for b in bs]
                ok = sum(1 / 1.5 <= x <= 1.5 for x in q)
                t = totals.setdefault((light, w), [0, 0])
                t[0] += ok
                t[1] += len(q)
                cells.append("%d/%d, %.2f" % (ok, len(q), statistics.median(q)))
            out.append("| %s | %g | %s |" % (scene, light, " | ".join(cells)))
        out.append("| **all** | %g | %s |" % (light, " | ".join(
            "**%d/%d**" % tuple(totals[(light, w)]) for w in WINDOWS)))
    return "\n".join(out) + ("\n\nEach cell: batches with measured / expected within 1.5x, "
                             "and its median.")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("build", nargs="?", default=os.path.join(HERE, "..", "build"))
    ap.add_argument("--scenes", type=lambda v: v.split(","), default=FAMILIES)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--light", type=lambda v: [float(x) for x in v.split(",")], default=[1.0, 0.1])
    ap.add_argument("--max-points", type=int, default=160)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json")
    ap.add_argument("--from", dest="source")
    a = ap.parse_args()
    if a.source:
        with open(a.source) as f:
            print(tables(json.load(f)["results"]))
        return
    scenes, seeds, lights, max_points, jobs, json_out = (a.scenes, a.seeds, a.light, a.max_points,
                                                         a.jobs, a.json)
    ips = os.path.join(a.build, "cli", "ips")
    h = subprocess.run([ips, "simulate", "--help"], capture_output=True, text=True)
    peak = float(re.search(r"--peak-e E.*?\(default ([0-9.e+]+)\)", h.stdout + h.stderr,
                           re.S).group(1))
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(jobs) as pool:
        work = [(s, lt, sd) for s in scenes for lt in lights for sd in range(1, seeds + 1)]
        recs = list(pool.map(lambda a: one_scan(ips, *a, max_points, peak, tmp), work))
    took = time.monotonic() - t0
    if json_out:
        with open(json_out, "w") as f:
            json.dump({"seconds": took, "results": recs}, f)
    print(tables(recs))
    print("\nran in %.0f s" % took)


if __name__ == "__main__":
    main()
