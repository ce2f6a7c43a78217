#!/usr/bin/python3
"""numpy_peer.py: the NumPy peer of `ips fit`'s sweep, for speed comparisons (bench/speed.sh).

The peer is the straightforward vectorised method: the design matrix of eq. 3 by tensor
Gauss-Legendre quadrature (G x G nodes in every sub-pixel, the unit-peak Airy
[2 J1(a rho) / (a rho)]^2 summed with the product weights, a = pi Rz / R), then one
numpy.linalg.lstsq (LAPACK dgelsd) per r of the weighted problem W^1/2 A T = W^1/2 y with the
paper's sigma (eq. 5 as printed, the same as `ips fit`'s default), chi2 of the minimum.
J1 is SciPy's scipy.special.j1 (Cephes, ~33 ns a value here) when SciPy is installed
(python3-scipy), else the classic rational/asymptotic approximation (Numerical Recipes' bessj1,
|error| < 1e-8) in NumPy, about ten times slower: the script prints which one it used.

usage: numpy_peer.py SCAN.json [--r-min 1] [--r-max 16] [--nodes 8] [--json]
Prints per-r chi2 and the design / lstsq time of each r (process CPU and wall), or JSON.
"""
import argparse
import json
import sys
import time

import numpy as np

RZ = 1.2196698912665045  # j_{1,1} / pi


def j1_nr(x):
    """Bessel J1 (Numerical Recipes bessj1), vectorised, x >= 0."""
    out = np.empty_like(x)
    small = x < 8.0
    xs = x[small]
    y = xs * xs
    a1 = xs * (72362614232.0 + y * (-7895059235.0 + y * (242396853.1 + y * (
        -2972611.439 + y * (15704.48260 + y * (-30.16036606))))))
    a2 = 144725228442.0 + y * (2300535178.0 + y * (18583304.74 + y * (
        99447.43394 + y * (376.9991397 + y * 1.0))))
    out[small] = a1 / a2
    xl = x[~small]
    z = 8.0 / xl
    y = z * z
    xx = xl - 2.356194491
    b1 = 1.0 + y * (0.183105e-2 + y * (-0.3516396496e-4 + y * (0.2457520174e-5 + y * (
        -0.240337019e-6))))
    b2 = 0.04687499995 + y * (-0.2002690873e-3 + y * (0.8449199096e-5 + y * (
        -0.88228987e-6 + y * 0.105787412e-6)))
    out[~small] = np.sqrt(0.636619772 / xl) * (np.cos(xx) * b1 - z * np.sin(xx) * b2)
    return out


try:
    from scipy.special import j1
    J1_NAME = "scipy.special.j1"
except ImportError:
    j1 = j1_nr
    J1_NAME = "numpy bessj1 approximation"


def airy(v):
    """Unit-peak Airy [2 J1(v) / v]^2 (1 at v = 0)."""
    v = np.maximum(v, 1e-300)
    return np.where(v < 1e-8, 1.0, (2.0 * j1(v) / v) ** 2)


def design(xs, ys, pitch, r, a, nodes, chunk_nodes=1 << 16):
    """n x r^2 design matrix, column j*r + i = sub-pixel (i, j), by tensor Gauss-Legendre."""
    t, wt = np.polynomial.legendre.leggauss(nodes)
    h = pitch / r
    u = ((np.arange(r)[:, None] + (t[None, :] + 1) / 2) * h).ravel()  # r*G nodes per axis
    wu = np.tile(wt * h / 2, r)
    ww = wu[:, None] * wu[None, :]
    n = len(xs)
    A = np.empty((n, r * r))
    chunk = max(1, chunk_nodes // (r * nodes) ** 2)  # spots per block: small temporaries
    for k0 in range(0, n, chunk):
        dx = u[None, :] - xs[k0:k0 + chunk, None]
        dy = u[None, :] - ys[k0:k0 + chunk, None]
        rho = np.sqrt(dy[:, :, None] ** 2 + dx[:, None, :] ** 2)  # spot, y node, x node
        f = airy(a * rho) * ww[None, :, :]
        c = f.shape[0]
        A[k0:k0 + c] = f.reshape(c, r, nodes, r, nodes).sum(axis=(2, 4)).reshape(c, r * r)
    return A


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scan")
    ap.add_argument("--r-min", type=int, default=1)
    ap.add_argument("--r-max", type=int, default=16)
    ap.add_argument("--nodes", type=int, default=8, help="Gauss-Legendre nodes per sub-pixel side")
    ap.add_argument("--json", action="store_true")
    o = ap.parse_args()
    with open(o.scan) as f:
        s = json.load(f)
    x = np.array(s["x_um"], float)
    y = np.array(s["y_um"], float)
    sig = np.array(s["signal_dn"], float)
    fs = s.get("full_scale_dn", 0) or 0
    use = np.isfinite(x) & np.isfinite(y) & np.isfinite(sig)
    if fs > 0:
        use &= sig < fs
    x, y, sig = x[use], y[use], sig[use]
    frames = s.get("frames", 1)
    d = sig - s["bias_dn"]
    rg = s["read_noise_e"] / s["gain_e_per_dn"]
    sigma = np.sqrt((np.maximum(d, 0) + rg * rg) / frames)  # eq. 5 as printed
    sigma = np.maximum(sigma, np.sqrt(1.0 / 12 / frames))
    sw = 1 / sigma
    a = np.pi * RZ / s["spot_radius_um"]
    fits = []
    c0, w0 = time.process_time(), time.perf_counter()
    for r in range(o.r_min, o.r_max + 1):
        c1, w1 = time.process_time(), time.perf_counter()
        A = design(x, y, s["pitch_um"], r, a, o.nodes)
        c2, w2 = time.process_time(), time.perf_counter()
        T, _, rank, sv = np.linalg.lstsq(A * sw[:, None], d * sw, rcond=None)
        chi2 = float(np.sum(((d - A @ T) * sw) ** 2))
        c3, w3 = time.process_time(), time.perf_counter()
        fits.append({"r": r, "chi2": chi2, "rank": int(rank), "cond": float(sv[0] / sv[-1]),
                     "design_cpu_ms": (c2 - c1) * 1e3, "lstsq_cpu_ms": (c3 - c2) * 1e3,
                     "design_wall_ms": (w2 - w1) * 1e3, "lstsq_wall_ms": (w3 - w2) * 1e3})
    out = {"n": int(len(x)), "nodes": o.nodes, "j1": J1_NAME, "fits": fits,
           "total_cpu_ms": (time.process_time() - c0) * 1e3,
           "total_wall_ms": (time.perf_counter() - w0) * 1e3}
    if o.json:
        json.dump(out, sys.stdout)
        print()
        return
    print(f"{'r':>3} {'chi2':>14} {'design ms':>10} {'lstsq ms':>9}  (CPU)")
    for f in fits:
        print(f"{f['r']:3d} {f['chi2']:14.6g} {f['design_cpu_ms']:10.1f} {f['lstsq_cpu_ms']:9.1f}")
    print(f"total CPU {out['total_cpu_ms']:.0f} ms, wall {out['total_wall_ms']:.0f} ms, "
          f"{out['n']} points, {o.nodes} x {o.nodes} nodes per sub-pixel, J1 by {J1_NAME}")


if __name__ == "__main__":
    main()
