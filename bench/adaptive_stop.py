#!/usr/bin/env python3
"""adaptive_stop.py [BUILD_DIR] [--scenes A,B] [--seeds N] [--targets T1,T2] [--max-points N]
[--rules]: how honest an adaptive scan's stop on a target is (`ips simulate --adaptive
--target-err T`, fit/adapt_plan.h's stop rule), on the simulated bench against its truth; prints
figures (never pass/fail).

Per scene family and target, one scan a seed (seeds 1..N, 5 x 5 start, batches of 9, at most
--max-points): how many stopped on the target (the others on the budget), the points at the stop
(median, range), and at the stop the map's rms against the truth (the summary's rms_err_truth:
the scene's own 10 x 10 cells, sampled as the fidelity harness samples) over the expected error
it stopped on (median, range, how many above 1.5x) and over the target (median, max, how many
above 1.5x). An honest stop has both near 1 and none far above.

--rules: the stop rules compared on the same scans instead: one scan a seed with no target (the
points taken do not depend on the target, only where the scan stops), then for every target of
0.008..0.025 where each rule would have stopped, and the same figures over all of them. The rules
use only what the summary's batches say (expected_err, r, smooth): R0 the first plan with e <= T;
R1 two plans in a row; R2 one plan whose model (r, smooth) is the plan before's; R3 both; R4
three plans in a row; R5 the first plan with e <= T after the starting raster's (what
fit/adapt_plan.h does).
"""
import json
import os
import statistics
import subprocess
import sys
import tempfile

RULE_TARGETS = [0.008, 0.009, 0.010, 0.011, 0.012, 0.013, 0.014, 0.015, 0.016, 0.017, 0.018,
                0.020, 0.025]


def same(a, b):
    return a["r"] == b["r"] and a["smooth"] == b["smooth"]


def met(b, t):
    return b["expected_err"] <= t


RULES = [
    ("R0 first plan at the target", lambda bs, k, t: met(bs[k], t)),
    ("R1 two plans in a row", lambda bs, k, t: k > 0 and met(bs[k], t) and met(bs[k - 1], t)),
    ("R2 one plan, model unchanged", lambda bs, k, t: k > 0 and met(bs[k], t) and
     same(bs[k], bs[k - 1])),
    ("R3 two in a row, model unchanged", lambda bs, k, t: k > 0 and met(bs[k], t) and
     met(bs[k - 1], t) and same(bs[k], bs[k - 1])),
    ("R4 three plans in a row", lambda bs, k, t: k > 1 and all(met(bs[j], t)
                                                              for j in (k - 2, k - 1, k))),
    ("R5 first plan after the start", lambda bs, k, t: k > 0 and met(bs[k], t)),
]


def summary(stops):
    """stops: (points, rms, expected, target) at the stops on a target."""
    if not stops:
        return "no stop on the target"
    pts = [s[0] for s in stops]
    q = [s[1] / s[2] for s in stops]
    qt = [s[1] / s[3] for s in stops]
    return ("points %d (%d-%d) | rms / expected %.2f (%.2f-%.2f), %d above 1.5x | rms / target "
            "%.2f (max %.2f), %d above 1.5x"
            % (statistics.median(pts), min(pts), max(pts), statistics.median(q), min(q), max(q),
               sum(x > 1.5 for x in q), statistics.median(qt), max(qt),
               sum(x > 1.5 for x in qt)))


def main():
    args = sys.argv[1:]
    build = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "build")
    scenes, seeds, max_points = ["dip:10", "gradient:10", "softedge:10"], 5, 162
    targets, rules = [0.01, 0.015, 0.02], False
    while args:
        a = args.pop(0)
        if a == "--scenes":
            scenes = args.pop(0).split(",")
        elif a == "--seeds":
            seeds = int(args.pop(0))
        elif a == "--targets":
            targets = [float(x) for x in args.pop(0).split(",")]
        elif a == "--max-points":
            max_points = int(args.pop(0))
        elif a == "--rules":
            rules = True
        else:
            build = a
    ips = os.path.join(build, "cli", "ips")

    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "a.json")

        def scan(scene, seed, target):
            r = subprocess.run([ips, "simulate", "--scene", scene, "--seed", str(seed),
                                "--adaptive", "--target-err", repr(target), "--max-points",
                                str(max_points), "-o", out],
                               capture_output=True, text=True, check=True)
            return json.loads(r.stdout)["adaptive"]

        if rules:
            stops = {name: [] for name, _ in RULES}
            budget = {name: 0 for name, _ in RULES}
            for scene in scenes:
                for seed in range(1, seeds + 1):
                    bs = scan(scene, seed, 1e-6)["batches"]
                    for t in RULE_TARGETS:
                        for name, rule in RULES:
                            k = next((k for k in range(len(bs)) if rule(bs, k, t)), None)
                            if k is None:
                                budget[name] += 1
                            else:
                                b = bs[k]
                                stops[name].append((b["points"], b["rms_err_truth"],
                                                    b["expected_err"], t))
            n = len(scenes) * seeds * len(RULE_TARGETS)
            print("%d scans x %d targets (%s), at most %d points:"
                  % (len(scenes) * seeds, len(RULE_TARGETS), ", ".join(map(str, RULE_TARGETS)),
                     max_points))
            for name, _ in RULES:
                print("  %-33s %3d of %d stopped on the target | %s"
                      % (name, n - budget[name], n, summary(stops[name])))
            return

        for scene in scenes:
            for t in targets:
                stops, other = [], []
                for seed in range(1, seeds + 1):
                    ad = scan(scene, seed, t)
                    if ad["stop"] == "target":
                        stops.append((ad["points"], ad["rms_err_truth"], ad["expected_err"], t))
                    else:
                        other.append("%s at %d" % (ad["stop"], ad["points"]))
                    print("  %s seed %d target %g: %s at %d points, expected %.4f, rms %.4f"
                          % (scene, seed, t, ad["stop"], ad["points"], ad["expected_err"],
                             ad["rms_err_truth"]), file=sys.stderr)
                print("%s, target %g: %d of %d on the target%s | %s"
                      % (scene, t, len(stops), seeds,
                         " (%s)" % ", ".join(other) if other else "", summary(stops)))


if __name__ == "__main__":
    main()
