#!/usr/bin/env python3
"""geometry.py: the geometry fit (fit/geometry.h) against the simulator's truth on structured pixels.

For each scene family, raster and seed, `ips simulate` writes a scan whose true spot radius and
grid offset differ from the written ones (radius 0.9..1.6 um written 4 % small, offsets up to
0.2 um, chosen from the seed), and `ips fit --fit-geometry --sigma shot+read` recovers them, with
the r picked from the data (default) or asked (--geometry-r), refined under the kriged model
(`--geometry-model kriged`, the default) or kept as the r x r map's (`map`). Prints one line per
case (recovered R, dx, dy, their errors in um and in quoted sigmas, the r, status, chi2_red of the
model that made the geometry, ms) and the summary: the pass rate of the target (every parameter within 3 quoted sigma and within 0.03 um of the
truth), the worst cases and the time per fit. A benchmark: it prints, it never fails on numbers.
Usage: bench/geometry.py [--ips build/cli/ips] [--seeds N] [--geometry-r R] [--families a,b]
[--rasters 9,13,19] [--geometry-model kriged|map]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

RASTERS = {9: 0.6, 13: 0.42, 19: 0.3}
RADII = [0.9, 1.15, 1.4, 1.6]
OFFSETS = [(-0.15, 0.05), (0.2, -0.1), (0.08, 0.18), (-0.2, -0.2)]


def case(ips, fam, grid, seed, geometry_r, tmp, model="map"):
    R = RADII[(seed + grid) % len(RADII)]
    dx, dy = OFFSETS[(seed + len(fam)) % len(OFFSETS)]
    path = os.path.join(tmp, "s.scan")
    subprocess.run([ips, "simulate", "--scene", fam, "--grid", str(grid), "--step",
                    str(RASTERS[grid]), "--radius", str(R), "--written-radius", "%.4f" % (R * 0.96),
                    "--offset", "%g,%g" % (dx, dy), "--seed", str(seed), "-o", path],
                   check=True, capture_output=True)
    cmd = [ips, "fit", path, "--sigma", "shot+read", "--fit-geometry", "--r-max", "2",
           "--threads", "1"]
    if geometry_r:
        cmd += ["--geometry-r", str(geometry_r)]
    cmd += ["--geometry-model", model]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode:
        return dict(fam=fam, grid=grid, seed=seed, fail=p.stderr.strip())
    d = json.loads(p.stdout)
    g = d["geometry"]
    truth = (R, dx, dy)
    got = (g["spot_radius_um"], g["dx_um"], g["dy_um"])
    sig = (g["spot_radius_um_err"], g["dx_um_err"], g["dy_um_err"])
    err = [a - b for a, b in zip(got, truth)]
    pull = [e / s if s else float("inf") for e, s in zip(err, sig)]
    ok = all(abs(e) <= 0.03 for e in err) and all(abs(z) <= 3 for z in pull)
    return dict(fam=fam, grid=grid, seed=seed, R=R, err=err, pull=pull, sig=sig, r=g["r"],
                status=g["status"],
                chi2_red=(g.get("kriged_fit") or {}).get("chi2_red", g["chi2_red"]), ms=d["timing_ms"]["geometry"], ok=ok,
                ok_um=all(abs(e) <= 0.03 for e in err), ok_sig=all(abs(z) <= 3 for z in pull))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ips", default="build/cli/ips")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--geometry-r", type=int, default=0)
    ap.add_argument("--families", default="paperlike,dip,edge,deadcorner")
    ap.add_argument("--rasters", default="9,13,19")
    ap.add_argument("--geometry-model", default="kriged", choices=["kriged", "map"])
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for grid in [int(x) for x in a.rasters.split(",")]:
            for fam in a.families.split(","):
                for seed in range(1, a.seeds + 1):
                    c = case(a.ips, fam, grid, seed, a.geometry_r, tmp, a.geometry_model)
                    rows.append(c)
                    if "fail" in c:
                        print("%-10s %2dx%-2d seed %d  FAILED: %s" % (fam, grid, grid, seed,
                                                                      c["fail"]))
                        continue
                    print("%-10s %2dx%-2d seed %d R %.2f  r %2d  err R %+.3f dx %+.3f dy %+.3f um"
                          "  pulls %+5.1f %+5.1f %+5.1f  %-8s chi2_red %5.2f  %6.0f ms %s" %
                          (fam, grid, grid, seed, c["R"], c["r"], *c["err"], *c["pull"],
                           c["status"], c["chi2_red"], c["ms"], "pass" if c["ok"] else "MISS"),
                          flush=True)
    done = [c for c in rows if "fail" not in c]
    print("\npass (3 sigma and 0.03 um): %d / %d; within 0.03 um: %d; within 3 sigma: %d; "
          "poor_fit: %d; failed: %d" %
          (sum(c["ok"] for c in done), len(rows), sum(c["ok_um"] for c in done),
           sum(c["ok_sig"] for c in done), sum(c["status"] == "poor_fit" for c in done),
           len(rows) - len(done)))
    for grid in sorted({c["grid"] for c in done}):
        g = [c for c in done if c["grid"] == grid]
        ms = sorted(c["ms"] for c in g)
        mx = max(max(abs(e) for e in c["err"]) for c in g)
        print("%2dx%-2d: pass %d / %d, worst |error| %.3f um, median %.0f ms, max %.0f ms" %
              (grid, grid, sum(c["ok"] for c in g), len(g), mx, ms[len(ms) // 2], ms[-1]))
    worst = sorted(done, key=lambda c: -max(abs(e) for e in c["err"]))[:3]
    for c in worst:
        print("worst: %s %dx%d seed %d: err %+.3f %+.3f %+.3f um, pulls %+.1f %+.1f %+.1f, r %d"
              % (c["fam"], c["grid"], c["grid"], c["seed"], *c["err"], *c["pull"], c["r"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
