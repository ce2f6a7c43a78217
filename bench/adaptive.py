#!/usr/bin/env python3
"""adaptive.py [BUILD_DIR] [--scenes A,B] [--seeds N] [--max-points N]: how many points an
adaptive scan (`ips simulate --adaptive`, fit/adapt_plan.h) needs to reach the kriged map's error
that the paper's 9 x 9 raster reaches, on the simulated bench against its truth; prints figures
(never pass/fail).

Per scene family and seed: the 9 x 9 raster at 0.6 um (`--grid 9`), fitted by `ips fit --sigma
shot+read`: its kriged map's rms against the truth (e9, the scene's own 10 x 10 cells, sampled as
the fidelity harness samples) and its expected error (the rms of its S_err, E9). Then one
adaptive scan (5 x 5 start, batches of 9, no target, up to --max-points): after each batch the
summary gives the refitted map's expected error and its rms against the truth (the map `ips fit`
gives of the same points). Reported: the points at the first batch whose measured rms is <= e9
(n_meas: what an oracle would stop at) and whose expected error is <= E9 (n_exp: what the
planner can see: the raster's own error bar reached); the adaptive map's rms at 81 points; and
the ratio of measured to expected error over every batch (median and range); and beside them
the smallest n x n raster of cell centres (n = 4..9, `--grid n --step 6/n`) whose kriged map is
as good as e9 (None: none up to 9 x 9 at that step). Medians over seeds, each seed in brackets.
"""
import json
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from fitdoc import rms_vs_truth  # noqa: E402


def main():
    args = sys.argv[1:]
    build = os.path.join(HERE, "..", "build")
    scenes, seeds, max_points = ["dip:10", "gradient:10", "softedge:10"], 5, 162
    while args:
        a = args.pop(0)
        if a == "--scenes":
            scenes = args.pop(0).split(",")
        elif a == "--seeds":
            seeds = int(args.pop(0))
        elif a == "--max-points":
            max_points = int(args.pop(0))
        else:
            build = a
    ips = os.path.join(build, "cli", "ips")

    def run(*a):
        return subprocess.run([ips, *a], capture_output=True, text=True, check=True).stdout

    print("| scene | 9 x 9 rms e9 (expected E9) | n_meas: rms <= e9 | n_exp: expected <= E9 | "
          "raster: rms <= e9 | adaptive rms at 81 | measured / expected |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        truth, grid, adapt = (os.path.join(tmp, n) for n in ("t.json", "g.json", "a.json"))
        for scene in scenes:
            rows = []
            for seed in range(1, seeds + 1):
                common = ["--scene", scene, "--seed", str(seed), "--truth", truth]
                run("simulate", *common, "--grid", "9", "--step", "0.6", "-o", grid)
                kr = json.loads(run("fit", grid, "--sigma", "shot+read"))["kriged_map"]
                with open(truth) as f:
                    t = [m for m in json.load(f)["maps"] if m["r"] == 10][0]
                e9 = rms_vs_truth(kr["S"], kr["grid"], t["S"], 10)
                E9 = (sum(e * e for e in kr["S_err"]) / len(kr["S_err"])) ** 0.5
                ad = json.loads(run("simulate", *common, "--adaptive", "--target-err", "1e-6",
                                    "--max-points", str(max_points), "-o", adapt))["adaptive"]
                bs = ad["batches"]
                n_meas = next((b["points"] for b in bs if b["rms_err_truth"] <= e9), None)
                n_exp = next((b["points"] for b in bs if b["expected_err"] <= E9), None)
                at81 = [b["rms_err_truth"] for b in bs if b["points"] <= 81][-1]
                n_raster = None  # the smallest n x n raster of cell centres as good as e9
                for n in range(4, 10):
                    run("simulate", *common, "--grid", str(n), "--step", repr(6.0 / n), "-o",
                        grid)
                    kr = json.loads(run("fit", grid, "--sigma", "shot+read"))["kriged_map"]
                    if rms_vs_truth(kr["S"], kr["grid"], t["S"], 10) <= e9:
                        n_raster = n * n
                        break
                ratios = [b["rms_err_truth"] / b["expected_err"] for b in bs]
                rows.append((e9, E9, n_meas, n_exp, at81, ratios, n_raster))
                print("  %s seed %d: e9 %.4f E9 %.4f n_meas %s n_exp %s raster %s at 81 %.4f "
                      "ratio %.2f-%.2f" % (scene, seed, e9, E9, n_meas, n_exp, n_raster, at81,
                                           min(ratios), max(ratios)), file=sys.stderr)

            def med(i):
                v = [r[i] for r in rows if r[i] is not None]
                return statistics.median(v) if v else float("nan")

            def miss(i):
                k = sum(r[i] is None for r in rows)
                return " (%d never)" % k if k else ""

            allr = [x for r in rows for x in r[5]]
            print("| %s | %.4f (%.4f) | %.0f%s [%s] | %.0f%s [%s] | %.0f%s [%s] | %.4f | "
                  "%.2f (%.2f-%.2f) |"
                  % (scene, med(0), med(1), med(2), miss(2),
                     ", ".join(str(r[2]) for r in rows), med(3), miss(3),
                     ", ".join(str(r[3]) for r in rows), med(6), miss(6),
                     ", ".join(str(r[6]) for r in rows), med(4),
                     statistics.median(allr), min(allr), max(allr)))


if __name__ == "__main__":
    main()
