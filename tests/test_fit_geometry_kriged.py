"""test_fit_geometry_kriged.py IPS: `ips fit --fit-geometry` refines the r x r fit's spot radius and
grid offset under the kriged model (fit/geometry_krige.c, the default `--geometry-model kriged`),
checked against the simulator's truth (`ips simulate --radius --written-radius --offset`, fixed
seeds):
- an edge pixel scanned 13 x 13, whose ramps no r x r map holds: R, dx, dy within 3 quoted sigma
  and within 0.03 um of the truth, status ok, and the kriged model's own chi2_red near 1 (its
  expectation N - 1 under the model, the noise model being the simulator's);
- a dead corner scanned 9 x 9: the same bounds;
- the dead-corner scan with its gain written 25 times too large, so the noise model's sigma is
  five times too small: status poor_fit, the kriged model's chi2_p < 1e-3 (its chi2_red stays far
  below 25: the fine grid's smooth part takes up much of the excess as structure);
- `--geometry-model map` keeps the r x r fit (model "map", kriged_fit null);
- `--table` reports the geometry the JSON gives, and which model made it;
- bad use exits 2 with one line: an unknown model, the option without --fit-geometry.
Runs in a temporary directory; Python's standard library only."""
import json
import os
import subprocess
import sys
import tempfile

from oklines import check, finish

IPS = sys.argv[1]


def simulate(tmp, scene, grid, step, R, dx, dy, seed):
    path = os.path.join(tmp, "%s_%d.scan" % (scene, grid))
    subprocess.run([IPS, "simulate", "--scene", scene, "--grid", str(grid), "--step", str(step),
                    "--radius", str(R), "--written-radius", "%.4f" % (R * 0.96),
                    "--offset", "%g,%g" % (dx, dy), "--seed", str(seed), "-o", path],
                   check=True, capture_output=True)
    return path


def fit(path, *extra):
    p = subprocess.run([IPS, "fit", path, "--sigma", "shot+read", "--fit-geometry", "--r-max", "2",
                        "--threads", "1", *extra], capture_output=True, text=True)
    check(p.returncode == 0, "%s: ips fit exits 0 (%d: %s)" % (path, p.returncode, p.stderr.strip()))
    return json.loads(p.stdout)["geometry"] if p.returncode == 0 else None


def near(g, truth, label):
    got = (g["spot_radius_um"], g["dx_um"], g["dy_um"])
    sig = (g["spot_radius_um_err"], g["dx_um_err"], g["dy_um_err"])
    print("%s: R %.4f +- %.4f, dx %.4f +- %.4f, dy %.4f +- %.4f (truth %s), %s, kriged chi2_red %.2f"
          % (label, got[0], sig[0], got[1], sig[1], got[2], sig[2], truth, g["status"],
             g["kriged_fit"]["chi2_red"]))
    for name, a, t, s in zip(("R", "dx", "dy"), got, truth, sig):
        check(0 < s < 0.1, "%s: sigma of %s %.4f in (0, 0.1) um" % (label, name, s))
        check(abs(a - t) <= 3 * s, "%s: %s %.4f within 3 sigma (%.4f) of the truth %.4f" %
              (label, name, a, s, t))
        check(abs(a - t) <= 0.03, "%s: %s %.4f within 0.03 um of the truth %.4f" % (label, name, a, t))


with tempfile.TemporaryDirectory() as tmp:
    for scene, grid, step, R, dx, dy, seed in [("edge", 13, 0.42, 1.4, 0.2, -0.1, 1),
                                               ("deadcorner", 9, 0.6, 1.6, 0.08, 0.18, 2)]:
        label = "%s %dx%d" % (scene, grid, grid)
        path = simulate(tmp, scene, grid, step, R, dx, dy, seed)
        g = fit(path)
        if not g:
            continue
        check(g["model"] == "kriged", "%s: model kriged (%s)" % (label, g["model"]))
        check(g["status"] == "ok", "%s: status ok (%s)" % (label, g["status"]))
        kf = g["kriged_fit"]
        check(0.7 < kf["chi2_red"] < 1.4 and kf["chi2_p"] > 1e-3,
              "%s: kriged chi2_red %.3f in (0.7, 1.4), chi2_p %.3g above 1e-3" %
              (label, kf["chi2_red"], kf["chi2_p"]))
        near(g, (R, dx, dy), label)
        if scene == "deadcorner":
            m = fit(path, "--geometry-model", "map")
            check(m and m["model"] == "map" and m["kriged_fit"] is None,
                  "--geometry-model map: model map, kriged_fit null (%r)" %
                  ((m["model"], m["kriged_fit"]) if m else None,))
            p = subprocess.run([IPS, "fit", path, "--sigma", "shot+read", "--fit-geometry",
                                "--r-max", "2", "--threads", "1", "--no-krige", "--table"],
                               capture_output=True, text=True)
            want = "spot radius %.4f +- %.4f um" % (g["spot_radius_um"], g["spot_radius_um_err"])
            check(p.returncode == 0 and "refined under the kriged model" in p.stdout and
                  want in p.stdout, "--table says the model and '%s'" % want)
            # the noise model five times too small: the gain written 25x too large
            with open(path) as f:
                doc = json.load(f)
            doc["gain_e_per_dn"] *= 25
            bad = os.path.join(tmp, "gain.scan")
            with open(bad, "w") as f:
                json.dump(doc, f)
            b = fit(bad)
            if b:
                print("gain x25: status %s, kriged chi2_red %.2f" % (b["status"],
                                                                     b["kriged_fit"]["chi2_red"]))
                check(b["status"] == "poor_fit" and b["kriged_fit"]["chi2_p"] < 1e-3 and
                      b["kriged_fit"]["chi2_red"] > 1.4,
                      "gain x25: poor_fit, chi2_p < 1e-3, chi2_red > 1.4 (%s, %r)" %
                      (b["status"], b["kriged_fit"]))
            for extra, what in [(["--fit-geometry", "--geometry-model", "spline"], "unknown model"),
                                (["--geometry-model", "map"], "without --fit-geometry")]:
                p = subprocess.run([IPS, "fit", path, *extra], capture_output=True, text=True)
                check(p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and
                      "geometry-model" in p.stderr,
                      "%s: exit 2 with one line naming --geometry-model (%d, %r)" %
                      (what, p.returncode, p.stderr))

finish()
