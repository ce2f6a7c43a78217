#!/usr/bin/env python3
"""test_simulate_adaptive.py IPS: `ips simulate --adaptive` (fit/adapt_plan.h, docs/numerics.md
"The planner"), end to end through the ips binary, against the simulator's truth (`--truth`, the
scenes' own 10 x 10 cells): on a dip and a gradient (two seeds each) an adaptive scan of 81 points
gives `ips fit` a kriged map no worse than 1.2x the 9 x 9 raster's (the same 81 points' worth) on
every scan and within 1.05x over all; the expected error it reports is within a factor 2 of the
error measured against the truth; the scan file holds the points the summary counts, all inside
the pixel, in batches of at most --batch after the starting raster; the summary's own error
against the truth is the one `ips fit`'s map has (the same map); the same seed writes the same
file; a target stops the scan at the first plan whose expected error is at or under it
(docs/numerics.md "An honest stop"), with the map within 1.5x of the target against the truth;
on the soft edges where a stop on the posterior's error alone stopped with the map 2.4-2.9x the
target (seeds 3 and 4, target 0.01) the posterior alone meets the target at some plan, and the
scan stops on it only with the map within 1.5x of it (else it runs to the budget); on a soft edge at a tenth of the light, where the
posterior under the recommended r's prior alone falls to a fifth of the error as r moves, the
expected error under the neighbouring priors is never below two thirds of the measured one (and
at most 2x it after the starting raster);
a budget stops at exactly --max-points; --dry-run prints the options; bad input exits 2 with one line naming the option."""
import json
import math
import os
import subprocess
import sys
import tempfile

from fitdoc import rms_vs_truth
from oklines import check, finish

IPS = sys.argv[1]
CASES = [("dip:10", 1), ("dip:10", 2), ("gradient:10", 1), ("gradient:10", 2)]


def run(*args):
    out = subprocess.run([IPS, *args], capture_output=True, text=True, check=True)
    return out.stdout


def kriged_rms(scan, truth):
    """The kriged map of `ips fit` (shot+read, as the planner fits) against the truth's cells."""
    doc = json.loads(run("fit", scan, "--sigma", "shot+read"))
    kr = doc["kriged_map"]
    with open(truth) as f:
        t = [m for m in json.load(f)["maps"] if m["r"] == 10][0]
    return rms_vs_truth(kr["S"], kr["grid"], t["S"], 10)


with tempfile.TemporaryDirectory() as tmp:
    truth, grid, adapt = (os.path.join(tmp, n) for n in ("truth.json", "grid.json", "adapt.json"))
    sq_grid = sq_adapt = 0.0
    for scene, seed in CASES:
        name = "%s seed %d" % (scene, seed)
        common = ["--scene", scene, "--seed", str(seed), "--truth", truth]
        run("simulate", *common, "--grid", "9", "--step", "0.6", "-o", grid)
        e_grid = kriged_rms(grid, truth)
        summary = json.loads(run("simulate", *common, "--adaptive", "--max-points", "81",
                                 "--target-err", "1e-4", "-o", adapt))
        ad = summary["adaptive"]
        e_adapt = kriged_rms(adapt, truth)
        check(summary["mode"] == "adaptive" and summary["points"] == 81 and
              ad["stop"] == "budget", "%s: 81 points, stopped by the budget (%s)"
              % (name, ad["stop"]))
        check(e_adapt <= 1.2 * e_grid, "%s: kriged map's rms against the truth: adaptive %.4f, "
              "9 x 9 raster %.4f (limit 1.2x)" % (name, e_adapt, e_grid))
        sq_grid += e_grid ** 2
        sq_adapt += e_adapt ** 2
        ratio = e_adapt / ad["expected_err"]
        check(0.5 <= ratio <= 2, "%s: expected error %.4f, measured %.4f (%.2fx, within 2x)"
              % (name, ad["expected_err"], e_adapt, ratio))
        check(abs(ad["rms_err_truth"] - e_adapt) <= 1e-6,
              "%s: the summary's error against the truth %.6f is ips fit's map's %.6f"
              % (name, ad["rms_err_truth"], e_adapt))
        with open(adapt) as f:
            doc = json.load(f)
        xs, ys = doc["x_um"], doc["y_um"]
        p = doc["pitch_um"]
        added = doc["adaptive"]["batches"]
        check(len(xs) == 81 and sum(added) == 81 and added[0] == 25 and
              all(1 <= a <= 9 for a in added[1:]),
              "%s: the file's 81 points in batches %s" % (name, added))
        check(all(0 < x < p and 0 < y < p for x, y in zip(xs, ys)),
              "%s: every position inside the pixel" % name)
        pts = [b["points"] for b in ad["batches"]]
        check(pts == [sum(added[:k + 1]) for k in range(len(added))] and
              all(b["expected_err"] > 0 for b in ad["batches"]),
              "%s: the summary's batches count the same points, each with its expected error"
              % name)
    check(sq_adapt <= 1.05 ** 2 * sq_grid, "over all: adaptive rms %.4f, raster %.4f"
          % (math.sqrt(sq_adapt / len(CASES)), math.sqrt(sq_grid / len(CASES))))

    # the same seed, the same scan file
    again = os.path.join(tmp, "again.json")
    run("simulate", "--scene", "gradient:10", "--seed", "2", "--adaptive", "--max-points", "81",
        "--target-err", "1e-4", "-o", again)
    with open(adapt, "rb") as f, open(again, "rb") as g:
        check(f.read() == g.read(), "the same seed writes the same scan file")

    # a target stops at the first plan that meets it
    s = json.loads(run("simulate", "--scene", "gradient:10", "--seed", "1", "--adaptive",
                       "--target-err", "0.009", "--truth", truth, "-o", adapt))["adaptive"]
    bs = s["batches"]
    errs = [b["expected_err"] for b in bs]
    check(s["stop"] == "target" and errs[-1] <= 0.009 and all(e > 0.009 for e in errs[:-1]),
          "target 0.009: stopped after %d points at %.4f, the first plan under it (%s; %s)"
          % (s["points"], errs[-1], s["stop"], errs))
    check(all(b["target_met"] == (b["expected_err"] <= 0.009) for b in bs),
          "each batch says whether it met the target")
    check(s["rms_err_truth"] <= 1.5 * 0.009, "target 0.009: the map %.4f from the truth"
          % s["rms_err_truth"])
    for seed in (3, 4):  # soft edges where the model changes at the batch that first meets 0.01
        s = json.loads(run("simulate", "--scene", "softedge:10", "--seed", str(seed),
                           "--adaptive", "--target-err", "0.01", "--max-points", "88",
                           "--truth", truth, "-o", adapt))["adaptive"]
        met = [b["points"] for b in s["batches"] if b["posterior_err"] <= 0.01]
        check(met and (s["stop"] != "target" or s["rms_err_truth"] <= 1.5 * 0.01),
              "softedge seed %d, target 0.01: the posterior alone met it at %s points; stopped "
              "(%s) at %d with the map %.4f from the truth"
              % (seed, met, s["stop"], s["points"], s["rms_err_truth"]))
    # a soft edge at a tenth of the light, where the recommended r moves 5 -> 6 at 79 points and
    # the 6 x 6 grid's prior drops the smooth part: the posterior under that prior alone falls
    # to a fifth of the error against the truth; the expected error under the neighbouring
    # priors is never below two thirds of it (at most 2x it after the start)
    s = json.loads(run("simulate", "--scene", "softedge:10", "--seed", "1", "--peak-e", "2150",
                       "--adaptive", "--target-err", "1e-6", "--max-points", "115",
                       "--truth", truth, "-o", adapt))["adaptive"]
    bs = s["batches"]
    ratios = ["%d: %.4f/%.4f" % (b["points"], b["rms_err_truth"], b["expected_err"]) for b in bs]
    check(all(b["expected_err"] >= b["rms_err_truth"] / 1.5 for b in bs) and
          all(b["expected_err"] <= 2 * b["rms_err_truth"] for b in bs[1:]),
          "softedge at a tenth of the light: the expected error never below the measured one / "
          "1.5, and at most 2x it after the start (points: measured/expected %s)"
          % ", ".join(ratios))
    check(any(b["posterior_err"] < b["rms_err_truth"] / 3 for b in bs) and
          all(b["posterior_err"] <= b["expected_err"] * (1 + 1e-12) for b in bs),
          "softedge at a tenth of the light: the posterior alone falls below a third of the "
          "measured error (%s), and never above the expected error"
          % ["%.4f" % b["posterior_err"] for b in bs])
    s = json.loads(run("simulate", "--scene", "dip:10", "--seed", "1", "--adaptive",
                       "--start-grid", "3", "--batch", "4", "--max-points", "18",
                       "--target-err", "1e-4", "-o", adapt))["adaptive"]
    check(s["stop"] == "budget" and s["points"] == 18 and
          [b["added"] for b in s["batches"]] == [9, 4, 4, 1],
          "budget 18 from a 3 x 3 start in batches of 4: %s"
          % [b["added"] for b in s["batches"]])

    # --dry-run says what it would do
    d = json.loads(run("simulate", "--adaptive", "--batch", "7", "--target-err", "0.02",
                       "--dry-run"))
    check(d["mode"] == "adaptive" and d["adaptive"] == {"start_grid": 5, "batch": 7,
                                                        "target_err": 0.02, "max_points": 300},
          "--dry-run: %s" % d.get("adaptive"))

    # bad input
    for args, word in ((["--target-err", "0"], "--target-err"),
                       (["--target-err", "-0.5"], "--target-err"),
                       (["--max-points", "20"], "--max-points"),
                       (["--batch", "0"], "--batch"),
                       (["--start-grid", "1"], "--start-grid")):
        r = subprocess.run([IPS, "simulate", "--adaptive", *args, "-o", adapt],
                           capture_output=True, text=True)
        lines = r.stderr.strip().splitlines()
        check(r.returncode == 2 and len(lines) == 1 and word in lines[0],
              "%s: exit %d, %r" % (" ".join(args), r.returncode, r.stderr.strip()))
    r = subprocess.run([IPS, "simulate", "--batch", "4", "-o", adapt], capture_output=True,
                       text=True)
    check(r.returncode == 2 and "--batch needs --adaptive" in r.stderr,
          "--batch without --adaptive: exit %d, %r" % (r.returncode, r.stderr.strip()))
finish()
