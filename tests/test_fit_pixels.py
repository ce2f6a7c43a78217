#!/usr/bin/env python3
"""test_fit_pixels.py IPS: `ips fit FILE --pixels all` on a scan file with a subframe
(docs/contracts.md), end to end through the ips binary.

A paperlike scan by the simulated bench with the paper's raster (5 x 5 pixels of 6 um in 0.6 um
steps) and a 7 x 7 sub-frame, written with every pixel of the sub-frame (`ips simulate
--write-subframe`), then fitted for every pixel:
- the covered pixels are the 25 of the raster, each with (6 / 0.6 - 1)^2 = 81 positions strictly
  inside (the raster's arithmetic); the other 24 are not_covered with a reason naming the edge
  the raster does not reach, and no fit;
- every covered pixel's r = 7 map matches the simulator's truth (`--truth`: the simulated
  sensor's pixels share the scene's map) as the single-pixel test does (test_simulate.sh: rms
  below 0.03, the dips at the top, left and bottom edges, none on the right);
- the POI's document is `ips fit FILE` with the same options (every number the same; only the
  times differ), and so is a neighbour's against `ips fit` of the file `ips simulate --pixel`
  writes for that pixel alone from the same seed (an independent extraction of its positions);
- without --pixels the output is unchanged: the same as for the file without its subframe;
- bad input exits 2 with one line on stderr naming the field or option."""
import json
import math
import os
import subprocess
import sys
import tempfile

from fitdoc import untimed
from oklines import check, fails, finish

IPS = sys.argv[1]
SUB, AREA, STEP, PITCH = 7, 5, 0.6, 6.0
INSIDE = (round(PITCH / STEP) - 1) ** 2
COVERED = {(dc, dr) for dc in range(-2, 3) for dr in range(-2, 3)}
SIM = ["--scene", "paperlike", "--seed", "3", "--subframe", str(SUB), "--area", str(AREA),
       "--step", str(STEP)]




def run(*args, code=0):
    p = subprocess.run([IPS, *args], capture_output=True, text=True)
    if p.returncode != code:
        print("ips %s: exit %d, stderr %s" % (" ".join(args), p.returncode, p.stderr))
    return p


def load(path):
    with open(path) as f:
        return json.load(f)


def edges(S, r=7):
    inner = range(1, r - 1)
    top = sum(S[i] for i in inner) / (r - 2)
    bottom = sum(S[(r - 1) * r + i] for i in inner) / (r - 2)
    left = sum(S[j * r] for j in inner) / (r - 2)
    right = sum(S[j * r + r - 1] for j in inner) / (r - 2)
    mid = sum(S[j * r + i] for j in inner for i in inner) / (r - 2) ** 2
    return top, left, bottom, right, mid


def matches_truth(S, T):
    """test_simulate.sh's check of one map against the truth."""
    e = math.sqrt(sum((x - y) ** 2 for x, y in zip(S, T)) / len(T))
    top, left, bottom, right, mid = edges(S)
    return e, (e < 0.03 and all(mid - x > 0.08 for x in (top, left, bottom))
               and abs(right - mid) < 0.06)


def bad_input(t, whole):
    """Each broken subframe: exit 2, one line on stderr naming the field (on the first 20 points
    of the scan: the checks are of the structure, and small files keep the ASan build quick)."""
    n = 20
    base = dict(whole, x_um=whole["x_um"][:n], y_um=whole["y_um"][:n],
                signal_dn=whole["signal_dn"][:n],
                subframe=dict(whole["subframe"], signal_dn=whole["subframe"]["signal_dn"][:n]))
    mm = SUB * SUB
    cases = {
        "not an object": ([1, 2], "subframe must be an object"),
        "even sub_px": (dict(base["subframe"], sub_px=SUB - 1), "subframe.sub_px"),
        "sub_px not a number": (dict(base["subframe"], sub_px="7"), "subframe.sub_px"),
        "no step": ({k: v for k, v in base["subframe"].items() if k != "step_um"},
                    "subframe.step_um"),
        "signal_dn not an array": (dict(base["subframe"], signal_dn={"a": 1}),
                                   "subframe.signal_dn"),
        "a point not an array": (dict(base["subframe"], signal_dn=[5.0] * n),
                                 "subframe.signal_dn"),
        "wrong size (sub_px 5 for 7 x 7 frames)": (dict(base["subframe"], sub_px=5),
                                                   "subframe.signal_dn"),
        "one point short": (dict(base["subframe"], signal_dn=base["subframe"]["signal_dn"][1:]),
                            "subframe.signal_dn"),
        "a string in a frame": (dict(base["subframe"], signal_dn=[["x"] * mm] * n),
                                "subframe.signal_dn"),
        "centre not the POI's signal": (
            dict(base["subframe"], signal_dn=[[v + 1 for v in f] for f in
                                              base["subframe"]["signal_dn"]]),
            "subframe.signal_dn"),
    }
    for what, (sub, field) in cases.items():
        path = os.path.join(t, "bad.json")
        with open(path, "w") as f:
            json.dump(dict(base, subframe=sub), f)
        for args in (["fit", path, "--pixels", "all"], ["fit", path]):
            p = run(*args, code=2)
            lines = p.stderr.strip().splitlines()
            check(p.returncode == 2 and len(lines) == 1 and field in lines[0] and not p.stdout,
                  "%s (%s): exit 2, one line naming %s: %s" % (what, " ".join(args[2:]) or
                                                               "one pixel", field,
                                                               lines[:1]))
    plain = os.path.join(t, "plain.json")
    with open(plain, "w") as f:
        json.dump({k: v for k, v in base.items() if k != "subframe"}, f)
    for args, word in (([plain, "--pixels", "all"], "subframe"),
                       ([os.path.join(t, "sub.json"), "--pixels", "some"], "--pixels"),
                       ([os.path.join(t, "sub.json"), "--pixels", "all", "--table"], "--table")):
        p = run("fit", *args, code=2)
        lines = p.stderr.strip().splitlines()
        check(p.returncode == 2 and len(lines) == 1 and word in lines[0],
              "ips fit %s: exit 2 naming %s" % (" ".join(args[1:]), word))
    for extra, word in ((["--grid", "9"], "--grid"), (["--pixel", "1,0"], "--pixel")):
        p = run("simulate", *SIM, "--write-subframe", *extra, "-o", os.path.join(t, "x.json"),
                code=2)
        lines = p.stderr.strip().splitlines()
        check(p.returncode == 2 and len(lines) == 1 and word in lines[0],
              "ips simulate --write-subframe %s: exit 2 naming %s" % (" ".join(extra), word))


def main(t):
    sub, truth = os.path.join(t, "sub.json"), os.path.join(t, "truth.json")
    run("simulate", *SIM, "--write-subframe", "--truth", truth, "-o", sub)
    base = load(sub)
    T = [m for m in load(truth)["maps"] if m["r"] == 7][0]["S_normalised"]
    nx = round(AREA * PITCH / STEP) + 1
    check(len(base["x_um"]) == nx * nx and base["subframe"]["sub_px"] == SUB and
          len(base["subframe"]["signal_dn"]) == nx * nx and
          all(len(f) == SUB * SUB for f in base["subframe"]["signal_dn"]),
          "the file has every one of the %d raster points with a %d x %d sub-frame each"
          % (nx * nx, SUB, SUB))
    c = SUB * SUB // 2
    check(all(f[c] == s for f, s in zip(base["subframe"]["signal_dn"], base["signal_dn"])),
          "the sub-frame's centre is the POI's signal")

    p = run("fit", sub, "--pixels", "all")
    doc = json.loads(p.stdout)
    px = {(e["dcol"], e["drow"]): e for e in doc["pixels"]}
    check(len(doc["pixels"]) == SUB * SUB and
          [(e["dcol"], e["drow"]) for e in doc["pixels"]] ==
          [(dc, dr) for dr in range(-3, 4) for dc in range(-3, 4)],
          "every pixel of the sub-frame, row by row from the top left")
    fitted = {k for k, e in px.items() if e["status"] == "fitted"}
    check(fitted == COVERED and doc["covered"] == 25 and doc["fitted"] == 25 and
          doc["not_covered"] == SUB * SUB - 25 and doc["failed"] == 0,
          "the 25 pixels of the 5 x 5 raster are fitted, the other 24 not")
    check(all(px[k]["n_inside"] == INSIDE and px[k]["reason"] is None for k in COVERED),
          "each covered pixel has %d positions inside" % INSIDE)
    nc = [e for k, e in px.items() if k not in COVERED]
    check(all(e["status"] == "not_covered" and e["fit"] is None and "does not reach" in e["reason"]
              for e in nc), "the others are not_covered, with the edge the raster misses")
    check(all(("left" in px[(-3, r)]["reason"]) for r in range(-2, 3)),
          "the column left of the raster misses its left edge")
    worst = 0
    for k in sorted(COVERED):
        S = [f for f in px[k]["fit"]["fits"] if f["r"] == 7][0]["S"]
        e, good = matches_truth(S, T)
        worst = max(worst, e)
        check(good, "pixel %+d,%+d: r = 7 map rms %.4f from the truth, edges as the scene's"
              % (k[0], k[1], e))
    print("largest rms of the 25 maps: %.4f" % worst)

    # the POI is ips fit of the file (same options), a neighbour ips fit of its own file
    opts = ["--r", "7", "--wiener", "--ftest", "top,left,bottom"]
    sel = json.loads(run("fit", sub, "--pixels", "all", *opts).stdout)
    one = json.loads(run("fit", sub, *opts).stdout)
    poi = [e for e in sel["pixels"] if (e["dcol"], e["drow"]) == (0, 0)][0]["fit"]
    check(untimed(poi) == untimed(one), "the POI's document is ips fit FILE's (options %s)"
          % " ".join(opts))
    own = os.path.join(t, "own.json")
    run("simulate", *SIM, "--all-points", "--pixel", "1,-2", "-o", own)
    mine = json.loads(run("fit", own, *opts).stdout)
    nb = [e for e in sel["pixels"] if (e["dcol"], e["drow"]) == (1, -2)][0]["fit"]
    check(untimed(nb) == untimed(mine),
          "pixel (+1, -2)'s document is ips fit of the file ips simulate --pixel 1,-2 writes")

    # without --pixels: the output without the subframe (the subframe is not read into it)
    plain = os.path.join(t, "plain.json")
    with open(plain, "w") as f:
        json.dump({k: v for k, v in base.items() if k != "subframe"}, f)
    a = json.loads(run("fit", sub, "--wiener").stdout)
    b = json.loads(run("fit", plain, "--wiener").stdout)
    check(untimed(a) == untimed(b) and list(a) == list(b),
          "without --pixels the document is the one of the file without its subframe")

    bad_input(t, base)


with tempfile.TemporaryDirectory(prefix="ips-pixels-") as tmp:
    main(tmp)
finish("FAIL: " if fails() else "PASS: ")
