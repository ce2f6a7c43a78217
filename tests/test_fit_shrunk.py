#!/usr/bin/env python3
"""test_fit_shrunk.py IPS: the `shrunk_map` of the `ips fit` document (fit/shrink.h;
docs/contracts.md), end to end through the ips binary, recomputed here from the document's own
fits (area overlaps by interval arithmetic, independent of fit/shrink.c): the map is r - 1's
projected onto the r grid plus a part of the detail D = S_r - P S_{r-1}, whose kept fraction is
`factor`, `detail_rms` is D's rms, the resolution error `S_res` is 0.4 of the kept detail, the mean
is 1; and against the simulator's truth (`ips
simulate --truth`): over these scans the shrunk maps are closer to it than the recommended ones. A flat pixel (recommended r = 1) has none; `--table` prints it."""
import json
import math
import os
import subprocess
import sys
import tempfile

from debian_python import rerun_under_debian_python
from fitdoc import rms_vs_truth
from oklines import check, finish

try:
    from astropy.io import fits
except ImportError:
    rerun_under_debian_python()  # Debian's python3-astropy is for Debian's python3
    fits = None

IPS = sys.argv[1]
# graded pixels (10 x 10 cells, so the truth file's r = 10 maps are the scenes themselves) at the
# bench's light and a tenth of it
CASES = [(scene, seed, peak) for scene in ("softedge:10", "gradient:10", "dip:10")
         for seed, peak in ((5, 2150), (3, 21500))]



def overlap_1d(r, q):
    """w[a][b]: the fraction of fine cell a (of r) that coarse cell b (of q) covers."""
    return [[max(0.0, min((a + 1) / r, (b + 1) / q) - max(a / r, b / q)) * r for b in range(q)]
            for a in range(r)]


def project(S, q, r):
    w = overlap_1d(r, q)
    return [sum(w[j][l] * w[i][k] * S[l * q + k] for l in range(q) for k in range(q))
            for j in range(r) for i in range(r)]


def fit(path, *opts):
    out = subprocess.run([IPS, "fit", path, *opts], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


with tempfile.TemporaryDirectory() as tmp:
    err_rec = err_sh = 0.0
    for scene, seed, peak in CASES:
        scan, truth = os.path.join(tmp, "scan.json"), os.path.join(tmp, "truth.json")
        subprocess.run([IPS, "simulate", "--scene", scene, "--seed", str(seed), "--grid", "9",
                        "--step", "0.6", "--peak-e", str(peak), "--truth", truth, "-o", scan],
                       check=True, capture_output=True)
        doc = fit(scan, "--r-max", "10")
        sh, r = doc.get("shrunk_map"), doc["recommended_r"]
        name = "%s seed %d, %d e-" % (scene, seed, peak)
        check(sh is not None and sh["r"] == r and sh["toward_r"] == r - 1,
              "%s: shrunk_map at the recommended r = %d toward r - 1" % (name, r))
        if sh is None:
            continue
        fine = [f for f in doc["fits"] if f["r"] == r][0]
        coarse = [f for f in doc["fits"] if f["r"] == r - 1][0]
        P = project(coarse["S"], r - 1, r)
        D = [a - b for a, b in zip(fine["S"], P)]
        kept = [a - b for a, b in zip(sh["S"], P)]
        d = r * r
        dd = sum(x * x for x in D)
        c = math.sqrt(sum(x * x for x in kept) / dd) if dd > 0 else 0.0
        check(abs(sh["factor"] - c) <= 1e-9 and 0 <= c <= 1,
              "%s: factor %.6f = |S - P S_r-1| / |S_r - P S_r-1| %.6f by hand" % (name, sh["factor"], c))
        check(abs(sh["detail_rms"] - math.sqrt(dd / d)) <= 1e-9, "%s: detail_rms by hand" % name)
        check(len(sh["S_res"]) == d and
              max(abs(a - 0.4 * abs(b)) for a, b in zip(sh["S_res"], kept)) <= 1e-9,
              "%s: S_res = 0.4 |S - P S_r-1| by hand (docs/contracts.md)" % name)
        check(abs(sum(sh["S"]) / d - 1) <= 1e-9, "%s: mean 1" % name)
        check(all(e > 0 for e in sh["S_err"]) and sh["noise_rms"] > 0 and sh["tau"] >= 0,
              "%s: S_err, noise_rms positive, tau >= 0" % name)
        with open(truth) as f:
            t = [x for x in json.load(f)["maps"] if x["r"] == 10][0]  # the scene's own cells
        e_rec, e_sh = rms_vs_truth(fine["S"], r, t["S"], 10), rms_vs_truth(sh["S"], r, t["S"], 10)
        print("     rms against the truth: recommended %.4f, shrunk %.4f (detail kept %.3f)"
              % (e_rec, e_sh, c))
        err_rec += e_rec * e_rec
        err_sh += e_sh * e_sh
    check(err_sh < err_rec, "the shrunk maps are closer to the truth than the recommended ones "
          "(sum of squares %.3g < %.3g)" % (err_sh, err_rec))
    # a flat pixel: r = 1 is recommended and there is no coarser map
    scan = os.path.join(tmp, "flat.json")
    subprocess.run([IPS, "simulate", "--scene", "uniform", "--grid", "9", "--step", "0.6",
                    "-o", scan], check=True, capture_output=True)
    doc = fit(scan, "--r-max", "8")
    check(doc["recommended_r"] == 1 and doc["shrunk_map"] is None,
          "flat pixel: recommended r = 1, shrunk_map null")
    scan = os.path.join(tmp, "scan.json")
    table = subprocess.run([IPS, "fit", scan, "--r-max", "10", "--table"], capture_output=True,
                           text=True, check=True).stdout
    check("Shrunk map, r = " in table, "--table prints the shrunk map")
    sh = fit(scan, "--r-max", "10")["shrunk_map"]
    want = "S_res rms %.3g;" % math.sqrt(sum(x * x for x in sh["S_res"]) / sh["r"] ** 2)
    check(want in table, "--table prints the resolution error's rms (%s)" % want)
    # ips export --shrunk: the shrunk map as FITS (read back by astropy, an independent reader)
    doc_path, out = os.path.join(tmp, "fit.json"), os.path.join(tmp, "shrunk.fits")
    with open(doc_path, "w") as f:
        json.dump(fit(scan, "--r-max", "10"), f)
    with open(doc_path) as f:
        sh = json.load(f)["shrunk_map"]
    p = subprocess.run([IPS, "export", doc_path, "--pitch", "6", "-o", out, "--shrunk"],
                       capture_output=True, text=True)
    check(p.returncode == 0, "ips export --shrunk: " + p.stderr.strip())
    if fits is None:
        print("skip astropy is missing: the exported file is not read back")
    else:
        with fits.open(out) as h:
            got_s, got_e = h["S", 1].data, h["S_ERR", 1].data
            check(got_s.shape == (sh["r"], sh["r"]) and
                  max(abs(a - b) for a, b in zip(got_s.ravel().tolist(), sh["S"])) == 0 and
                  max(abs(a - b) for a, b in zip(got_e.ravel().tolist(), sh["S_err"])) == 0,
                  "the FITS file holds the shrunk map and its S_err")
            check(h["S", 1].header.get("IPSMAP") == "shrunk",
                  "its header names the map: IPSMAP = 'shrunk'")
            check(("S_RES", 1) in h and
                  h["S_RES", 1].data.ravel().tolist() == sh["S_res"],
                  "the FITS file holds the shrunk map's S_res as ('S_RES', 1)")
    # the recommended map of the same document: its r is the shrunk map's, so it carries the
    # same resolution error (fit/shrink.h: one per grid)
    with open(doc_path) as f:
        rec_r = json.load(f)["recommended_r"]
    p = subprocess.run([IPS, "export", doc_path, "--pitch", "6", "-o", out], capture_output=True,
                       text=True)
    check(p.returncode == 0 and rec_r == sh["r"], "ips export of the recommended map: " +
          p.stderr.strip())
    if fits is not None and p.returncode == 0:
        with fits.open(out) as h:
            check(("S_RES", 1) in h and h["S_RES", 1].data.ravel().tolist() == sh["S_res"] and
                  h[0].header.get("NRESMAPS") == 1,
                  "the recommended map's file holds the shrunk map's S_res of its r")
        p = subprocess.run([IPS, "export", doc_path, "--pitch", "6", "-o", out, "--r",
                            str(rec_r - 1)], capture_output=True, text=True)
        with fits.open(out) as h:
            check(p.returncode == 0 and ("S_RES", 1) not in h and
                  h[0].header.get("NRESMAPS") == 0,
                  "another r's map has no S_RES (no resolution error known for its grid)")
    p = subprocess.run([IPS, "export", doc_path, "--pitch", "6", "-o", out, "--shrunk", "--r",
                        "3"], capture_output=True, text=True)
    check(p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "--r" in p.stderr,
          "--shrunk with --r: exit 2, one line naming them")
    flat_doc = os.path.join(tmp, "flatfit.json")
    with open(flat_doc, "w") as f:
        json.dump(fit(os.path.join(tmp, "flat.json"), "--r-max", "8"), f)
    p = subprocess.run([IPS, "export", flat_doc, "--pitch", "6", "-o", out, "--shrunk"],
                       capture_output=True, text=True)
    check(p.returncode == 2 and "no shrunk map" in p.stderr,
          "--shrunk of a flat pixel's document: exit 2, no shrunk map")

finish()
