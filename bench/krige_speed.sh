#!/usr/bin/env bash
# krige_speed.sh [BUILD_DIR] [RUNS]: the whole `ips fit` process with the kriged map (its default)
# beside the sweep alone (--no-krige) at every raster size ipsd accepts, printing figures (never
# pass/fail): the 81-point reference scan (tests/data/paperlike_scan.json), 19 x 19 (361 points,
# `ips simulate --grid 19 --step 0.3`), 41 x 41 (1681 points, --grid 41 --step 0.12) and the
# paper's whole 51 x 51 procedure with every point (`ips simulate --all-points`, fitted with
# `--region all`: 2601 points). RUNS runs of each (default 5), interleaved so both see the same
# load; CPU time (user + sys of the child, wait4) and wall time, min and median, and the kriged
# map's own timing_ms.krige and its likelihood evaluations.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
BUILD=${1:-$HERE/../build}
RUNS=${2:-5}
IPS=$BUILD/cli/ips
[ -x "$IPS" ] || { echo "krige_speed.sh: no $IPS (build first)" >&2; exit 2; }
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
"$IPS" simulate --grid 19 --step 0.3 --seed 1 -o "$TMP/g19.json" >/dev/null
"$IPS" simulate --grid 41 --step 0.12 --seed 1 -o "$TMP/g41.json" >/dev/null
"$IPS" simulate --all-points --seed 1 -o "$TMP/all.json" >/dev/null
exec python3 - "$IPS" "$HERE/../tests/data/paperlike_scan.json" "$TMP" "$RUNS" <<'PY'
import json, os, statistics, subprocess, sys, time

ips, ref, tmp, runs = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
cases = [("81 reference", ref, [], 20), ("361 (19 x 19)", tmp + "/g19.json", [], 200),
         ("1681 (41 x 41)", tmp + "/g41.json", [], 1000),
         ("2601 (51 x 51, --region all)", tmp + "/all.json", ["--region", "all"], 2000)]


def run(argv):
    out = os.path.join(tmp, "out.json")
    t0 = time.perf_counter()
    with open(out, "w") as f:
        p = subprocess.Popen(argv, stdout=f)
        _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    if status != 0:
        sys.exit("krige_speed.sh: %s failed" % " ".join(argv))
    with open(out) as f:
        doc = json.load(f)
    return ru.ru_utime + ru.ru_stime, wall, doc


print("ips fit as a whole process, %d runs each interleaved (ms; CPU = user + sys)\n" % runs)
print(f"  {'points':30} {'sweep CPU':>10} {'sweep wall':>11} {'+krige CPU':>11} {'+krige wall':>12}"
      f" {'krige ms':>9} {'evals':>6} {'target':>7}")
for name, path, extra, target in cases:
    base = [ips, "fit", path] + extra
    S, K = [], []
    for _ in range(runs):
        S.append(run(base + ["--no-krige"]))
        K.append(run(base))
    med = lambda xs: statistics.median(xs) * 1e3
    km = K[-1][2].get("kriged_map") or {}
    print(f"  {name:30} {med([x[0] for x in S]):10.1f} {med([x[1] for x in S]):11.1f}"
          f" {med([x[0] for x in K]):11.1f} {med([x[1] for x in K]):12.1f}"
          f" {statistics.median(x[2]['timing_ms'].get('krige', float('nan')) for x in K):9.1f}"
          f" {km.get('evaluations', 0):6d} {target:7d}")
print("\n(wall medians include whatever else the machine runs; target: the whole process with the"
      "\n kriged map, docs/numerics.md \"The kriged map's speed\")")
PY
