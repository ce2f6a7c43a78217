#!/usr/bin/env bash
# speed.sh [BUILD_DIR] [RUNS]: `ips fit` against its NumPy peer (bench/numpy_peer.py), side by
# side in one run, printing figures (never pass/fail).
#  1. The scale job: a 41 x 41 raster (`ips simulate --grid 41 --step 0.12`: the reference scan's
#     extent, 0.6..5.4 um in the 6 um pixel, R = 1.342 um, paper-like map, noise), fitted for
#     r = 1..16 by `ips fit --r-min 1 --r-max 16` and by the peer; RUNS runs of each (default 3),
#     interleaved so that both see the same load. `ips fit` runs twice: as it runs by default (the
#     sweep's r on as many threads as the process has CPUs, --threads) and on one thread
#     (--threads 1); the peer with OPENBLAS_NUM_THREADS=1, so that its CPU time is its work (its
#     BLAS is 4 % of it; a pool of BLAS threads only adds spinning). Per-process CPU time (user +
#     sys, from the kernel's accounting of the child, wait4) and wall time, min and median, the
#     ratios, and per r the design/solve figures of each. Wall time is what a user waits for;
#     CPU time is the work, and the fairer comparison on a shared machine.
#     (`--no-krige`: the peer computes the paper's sweep, not the kriged map.)
#  2. The reference job as whole processes: `ips fit tests/data/paperlike_scan.json --ftest
#     top,left,bottom --wiener` (81 points, r = 1..8) with --no-krige (the sweep alone) and as it
#     runs by default (with the kriged map) against /bin/true, 50 runs interleaved.
#     bench/krige_speed.sh has the kriged map at larger rasters.
# Needs /usr/bin/python3 with NumPy (python3-numpy; python3-scipy for the peer's J1), see
# scripts/deps.sh. The machine's other load shows in the wall times; CPU times are the fairer
# comparison on a shared machine.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
BUILD=${1:-$HERE/../build}
RUNS=${2:-3}
IPS=$BUILD/cli/ips
[ -x "$IPS" ] || { echo "speed.sh: no $IPS (build first)" >&2; exit 2; }
PY=/usr/bin/python3
[ -x "$PY" ] || PY=python3
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
"$IPS" simulate --grid 41 --step 0.12 --seed 1 -o "$TMP/raster41.json" >/dev/null
exec "$PY" - "$IPS" "$HERE/numpy_peer.py" "$TMP/raster41.json" "$HERE/../tests/data/paperlike_scan.json" "$RUNS" "$TMP" <<'EOF'
import json, os, statistics, subprocess, sys, time

ips, peer, scan, ref, runs, tmp = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5]), sys.argv[6]


def run(argv, out_path=None, env=None):
    """Runs argv to completion; returns (cpu_s, wall_s, stdout text)."""
    t0 = time.perf_counter()
    with open(out_path or os.devnull, "w") as out:
        p = subprocess.Popen(argv, stdout=out, env=env)
        _, status, ru = os.wait4(p.pid, 0)  # the child's own rusage (microseconds)
    wall = time.perf_counter() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode:
        sys.exit(f"speed.sh: {argv[0]} exited {p.returncode}")
    cpu = ru.ru_utime + ru.ru_stime
    text = open(out_path).read() if out_path else ""
    return cpu, wall, text


ips_cmd = [ips, "fit", scan, "--r-min", "1", "--r-max", "16", "--no-krige"]  # the peer's work
peer_cmd = [sys.executable, peer, scan, "--r-min", "1", "--r-max", "16", "--json"]
peer_env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
I, I1, P = [], [], []
for i in range(runs):
    I.append(run(ips_cmd, os.path.join(tmp, "ips.json")))
    I1.append(run(ips_cmd + ["--threads", "1"], os.path.join(tmp, "ips1.json")))
    P.append(run(peer_cmd, os.path.join(tmp, "peer.json"), peer_env))
fi = json.loads(I[-1][2])
fp = json.loads(P[-1][2])


def mm(v):
    return min(v), statistics.median(v)


ic, iw = mm([x[0] for x in I]), mm([x[1] for x in I])
i1c, i1w = mm([x[0] for x in I1]), mm([x[1] for x in I1])
pc, pw = mm([x[0] for x in P]), mm([x[1] for x in P])
fi1 = json.loads(I1[-1][2])
if [f["chi2"] for f in fi1["fits"]] != [f["chi2"] for f in fi["fits"]]:
    sys.exit("speed.sh: ips fit --threads 1 and the default differ")
print(f"Scale job: {fi['N']} points (41 x 41 raster, 0.12 um steps), r = 1..16, {runs} runs each, interleaved")
print(f"  peer: tensor Gauss-Legendre {fp['nodes']} x {fp['nodes']} nodes per sub-pixel, J1 by {fp['j1']}, numpy.linalg.lstsq per r\n")
print(f"  {'':22} {'CPU min':>9} {'CPU median':>11} {'wall min':>9} {'wall median':>12}   (s)")
print(f"  {'ips fit (' + str(fi['timing_ms']['threads']) + ' threads)':22} {ic[0]:9.3f} {ic[1]:11.3f} {iw[0]:9.3f} {iw[1]:12.3f}")
print(f"  {'ips fit --threads 1':22} {i1c[0]:9.3f} {i1c[1]:11.3f} {i1w[0]:9.3f} {i1w[1]:12.3f}")
print(f"  {'NumPy peer':22} {pc[0]:9.3f} {pc[1]:11.3f} {pw[0]:9.3f} {pw[1]:12.3f}")
print(f"  {'peer / ips':22} {pc[0]/ic[0]:9.1f} {pc[1]/ic[1]:11.1f} {pw[0]/iw[0]:9.1f} {pw[1]/iw[1]:12.1f}   (target >= 30)")
print(f"  {'peer / ips --threads 1':22} {pc[0]/i1c[0]:9.1f} {pc[1]/i1c[1]:11.1f} {pw[0]/i1w[0]:9.1f} {pw[1]/i1w[1]:12.1f}\n")
print(f"  {'r':>3} {'ips chi2':>14} {'peer chi2':>14} {'ips design':>11} {'ips solve':>10} {'peer design':>12} {'peer lstsq':>11}   (ms; ips wall, peer CPU; last run)")
for a, b in zip(fi["fits"], fp["fits"]):
    print(f"  {a['r']:3d} {a['chi2']:14.6g} {b['chi2']:14.6g} {a['timing_ms']['design']:11.1f} "
          f"{a['timing_ms']['solve']:10.1f} {b['design_cpu_ms']:12.1f} {b['lstsq_cpu_ms']:11.1f}")
print(f"  sum {'':29} {sum(a['timing_ms']['design'] for a in fi['fits']):11.1f} "
      f"{sum(a['timing_ms']['solve'] for a in fi['fits']):10.1f} "
      f"{sum(b['design_cpu_ms'] for b in fp['fits']):12.1f} {sum(b['lstsq_cpu_ms'] for b in fp['fits']):11.1f}")

n = 50
job = [ips, "fit", ref, "--ftest", "top,left,bottom", "--wiener"]
jobs = {"sweep": job + ["--no-krige"], "krige": job}
tru = ["/bin/true"]
J, T = {k: [] for k in jobs}, []
for i in range(n):
    T.append(run(tru))
    for k, argv in jobs.items():
        J[k].append(run(argv))
tc, tw = mm([x[0] for x in T]), mm([x[1] for x in T])
print(f"\nReference job as a whole process: ips fit paperlike_scan.json --ftest top,left,bottom --wiener"
      f"\n  (81 points, r = 1..8), {n} runs interleaved with /bin/true\n")
print(f"  {'':22} {'CPU min':>9} {'CPU median':>11} {'wall min':>9} {'wall median':>12}   (ms)")
for k, label, target in (("sweep", "--no-krige (sweep)", 10), ("krige", "default (kriged map)", 20)):
    jc, jw = mm([x[0] for x in J[k]]), mm([x[1] for x in J[k]])
    print(f"  {label:22} {jc[0]*1e3:9.2f} {jc[1]*1e3:11.2f} {jw[0]*1e3:9.2f} {jw[1]*1e3:12.2f}   (target <= {target})")
print(f"  {'/bin/true':22} {tc[0]*1e3:9.2f} {tc[1]*1e3:11.2f} {tw[0]*1e3:9.2f} {tw[1]*1e3:12.2f}")
print("  (CPU: user + sys of the child from wait4; the wall times include whatever else the machine runs)")
EOF
