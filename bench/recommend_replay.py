#!/usr/bin/env python3
"""recommend_replay.py: replays the recommended-r rule (fit/recommend.c) and the candidate rules
measured against it on the fits written by `ipsd-bench-fidelity --dump FILE`, and prints, per
rule, the cases whose pick is within 1.1x of the best r in hindsight (rms against the simulator's
truth) and the worst ratio, on the tuning seeds and on the held-out ones.

Usage: bench/recommend_replay.py [--tune-seeds A-B] [--check OUT] DUMP [DUMP ...]
  --tune-seeds: the seeds the rules may be tuned on (default 1-15); every other seed is held out
  --check OUT: the bench's printed table for the same runs (stdout of ipsd-bench-fidelity, one
               file per dump, in order): asserts that the replay picks what the C rule picked
Python 3 standard library only (docs/numerics.md, "The recommended r": the candidate rules); the
rule's settings are fit_recommend_opts_default's. A script for study, not part of the suite.
"""
import functools
import math
import sys

OK_RATIO = 1.1
RASTERS = ["9x9 @0.6", "13x13 @0.42", "19x19 @0.3", "51x51 full"]
# model.h: FIT_UNDERDETERMINED | FIT_UNCONSTRAINED | FIT_ILL_CONDITIONED | FIT_NO_SIGNAL |
# FIT_NO_POINTS, the flags recommend.c's UNTRUSTED names
UNTRUSTED = 1 | 2 | 4 | 32 | 256
DEFAULT = dict(ntc=0.25, w=2, coarse=1.5, esc=1.7, esc_ntc=0.5, esc_ratio=2, near=1.15, one_se=1,
               nested=1)


def load(path):
    """The dump's cases: F (fit) and R (residual) lines, then the case's C line."""
    cases, fits, sim = [], {}, None
    for line in open(path):
        t = line.split()
        if not t:
            continue
        if t[0] == "F":
            r = int(t[1])
            f = dict(r=r, flags=int(t[2]), n_used=int(t[3]), params=int(t[4]), chi2=float(t[5]),
                     chi2_red=float(t[6]), cv_chi2=float(t[7]), S=None, S_err=None, resid=None)
            v = [float(x) for x in t[8:]]
            if len(v) == 2 * r * r:
                f["S"], f["S_err"] = v[:r * r], v[r * r:]
            fits[r] = f
        elif t[0] == "R":
            fits[int(t[1])]["resid"] = [float(x) for x in t[3:]]
        elif t[0] == "K":  # --simcheck's picks: down, up, down else up
            sim = [int(x) for x in t[1:4]]
        elif t[0] == "C":
            rms = {i + 1: float(x) for i, x in enumerate(t[5:])}
            fin = [r for r in rms if math.isfinite(rms[r])]
            cases.append(dict(scene=t[1], raster=int(t[2]), flux=float(t[3]), seed=int(t[4]),
                              rms=rms, fits=fits, best=min(fin, key=rms.get) if fin else 0,
                              sim=sim))
            fits, sim = {}, None
    return cases


def ratio(c, r):
    """The bench's ratio: the pick's rms over the best's, floor 1e-3 (a flat pixel's r = 1)."""
    if not r or not c["best"] or not math.isfinite(c["rms"].get(r, math.nan)):
        return math.inf
    return c["rms"][r] / max(c["rms"][c["best"]], 1e-3)


# ---- the rule of fit/recommend.c, step by step ----

def noise_contrast(f):
    S, E, m = f["S"], f["S_err"], len(f["S"])
    mean = sum(S) / m
    return math.sqrt(sum(e * e for e in E) / m), math.sqrt(sum((s - mean) ** 2 for s in S) / m)


def expected_parts(f, scale):
    """fit_map_expected_error's noise^2 and resolution^2."""
    r, S, E = f["r"], f["S"], f["S_err"]
    v = dx = dy = 0.0
    for j in range(r):
        for i in range(r):
            s = S[j * r + i]
            v += E[j * r + i] ** 2
            if i + 1 < r:
                dx += (S[j * r + i + 1] - s) ** 2
            if j + 1 < r:
                dy += (S[(j + 1) * r + i] - s) ** 2
    n2, pairs = v / (r * r) * scale * scale, r * (r - 1)
    return n2, max((dx / pairs + dy / pairs - 4 * n2) / 12, 0)


def expected(f, scale, w):
    if f["S"] is None or f["r"] < 2:
        return math.nan
    n2, res2 = expected_parts(f, scale)
    return math.sqrt(w * n2 + res2)


def admissible(f, o, scale, ntc=None):
    if f["S"] is None or (f["flags"] & UNTRUSTED) or not math.isfinite(f["cv_chi2"]):
        return False
    if f["r"] == 1:
        return True
    n, c = noise_contrast(f)
    return n * scale <= (o["ntc"] if ntc is None else ntc) * c


def scatter_min(fits):
    """recommend.c's noise_scale: sqrt of the smallest reduced chi2 with dof >= N/4."""
    v = [f["chi2_red"] for f in fits.values()
         if f["S"] is not None and f["n_used"] - f["params"] >= 0.25 * f["n_used"]]
    best = min(v) if v else math.inf
    return math.sqrt(best) if math.isfinite(best) and best > 0 else 1


def loo_se(f):
    if f["resid"] is None or not f["chi2"] > 0 or not math.isfinite(f["cv_chi2"]):
        return math.nan
    k, terms = f["cv_chi2"] / f["chi2"], [f["cv_chi2"] / f["chi2"] * e * e
                                          for e in f["resid"] if math.isfinite(e)]
    n = len(terms)
    if n < 2:
        return math.nan
    mean = sum(terms) / n
    var = max(sum(t * t for t in terms) / n - mean * mean, 0)
    return math.sqrt(n * var * n / (n - 1))


def recommend(c, o=DEFAULT, scale_fn=scatter_min, info=None):
    """fit_recommend: steps 1-4 (recommend.h)."""
    fits = c["fits"]
    rmin, rmax = min(fits), max(fits)
    s = scale_fn(fits)
    adm = [r for r in sorted(fits) if admissible(fits[r], o, s)]
    if not adm:
        return 0
    rcv = min(adm, key=lambda r: (fits[r]["cv_chi2"], r))
    base, f0 = rcv, fits[rcv]
    se = loo_se(f0)
    if o["one_se"] > 0 and math.isfinite(se):
        for r in range(rmin, rcv):
            f = fits[r]
            if (admissible(f, o, s) and f["cv_chi2"] <= f0["cv_chi2"] + o["one_se"] * se and
                    (f["chi2_red"] <= o["coarse"] * s * s or
                     (o.get("nested", 0) and r > 1 and rcv % r == 0))):
                base = r
                break
    f0, rb = fits[base], base
    eb = expected(f0, s, o["w"])
    if o["w"] > 0 and math.isfinite(eb):
        for r in (base - 1, base + 1):
            if r < 2 or r < rmin or r > rmax or not admissible(fits[r], o, s):
                continue
            f = fits[r]
            if r > base and not f["chi2"] <= f0["chi2"]:
                continue
            if (r < base and not f["chi2_red"] <= o["coarse"] * s * s and
                    not (o["near"] > 0 and f["chi2_red"] <= o["near"] * f0["chi2_red"])):
                continue
            e = expected(f, s, o["w"])
            if e < eb:
                eb, rb = e, r
    out = rb
    if rb == base and o["esc"] > 0 and base + 1 <= rmax:
        f1 = fits[base + 1]
        if (f0["chi2_red"] > o["esc"] * max(f1["chi2_red"], s * s) and f1["chi2"] <= f0["chi2"]
                and admissible(f1, o, s, o["esc_ntc"])):
            e0, e1 = expected(f0, s, o["w"]), expected(f1, s, o["w"])
            if not math.isfinite(e0) or (o["esc_ratio"] > 0 and e1 <= o["esc_ratio"] * e0):
                out = base + 1
    if info is not None:
        info.update(rcv=rcv, base=base, scale=s, adm=adm)
    return out


# ---- candidates ----

def mean1(S):
    m = sum(S) / len(S)
    return [x / m for x in S]


@functools.lru_cache(None)
def overlap(r, q):
    """Lengths of the overlaps of the 1-D cells of an r grid and a q grid on [0, 1]."""
    return [[max(min((a + 1) / r, (b + 1) / q) - max(a / r, b / q), 0) for b in range(q)]
            for a in range(r)]


def dist2(S, r, T, q):
    """Mean square difference over the pixel of two piecewise-constant mean-1 maps."""
    S, T, O = mean1(S), mean1(T), overlap(r, q)
    st = sum(S[j * r + i] * T[l * q + k] * O[j][l] * O[i][k]
             for j in range(r) for l in range(q) if O[j][l]
             for i in range(r) for k in range(q) if O[i][k])
    return sum(x * x for x in S) / (r * r) + sum(x * x for x in T) / (q * q) - 2 * st


def pick_min(c, crit, o=DEFAULT):
    fits, s = c["fits"], scatter_min(c["fits"])
    adm = [r for r in sorted(fits) if admissible(fits[r], o, s)]
    return min(adm, key=lambda r: (crit(fits[r]), r)) if adm else 0


def gcv(f):
    n, p = f["n_used"], f["params"]
    return f["chi2"] / (n * (1 - p / n) ** 2) if p < n else math.inf


def risk_vs_richer(c, ref, w):
    """Risk of each r of the rule's window (one-SE pick +- 1) against a richer map q: bias^2 from
    the rendered distance, E|S_r - S_q|^2 = bias^2 + n_q^2 - n_r^2 (nested least squares), so
    risk_r = |S_r - S_q|^2 + w n_r^2 - n_q^2 + res_q^2 (q's own resolution error)."""
    info = {}
    rec = recommend(c, info=info)
    if not rec:
        return 0
    fits, s, base = c["fits"], info["scale"], info["base"]
    q = base + 1 if ref == "next" else max(info["adm"])
    if q < 2 or q not in fits or not admissible(fits[q], DEFAULT, s, 0.5):
        return rec
    fq = fits[q]
    nq2, resq2 = expected_parts(fq, s)
    best, bv = rec, math.inf
    for r in range(max(1, base - 1), base + 2):
        if r not in fits or not admissible(fits[r], DEFAULT, s):
            continue
        n2 = (noise_contrast(fits[r])[0] * s) ** 2 if r > 1 else 0
        v = (dist2(fits[r]["S"], r, fq["S"], q) if r != q else 0) + w * n2 - nq2 + resq2
        if v < bv:
            bv, best = v, r
    return best


def self_consistency(c, start, k):
    """Parametric check with each map as its own stand-in: simulate from S_r, refit at r - 1;
    r recovers its own map better when |S_r-1(A S_r) - S_r|^2 + n_r-1^2 > n_r^2, the noise-free
    bias being |S_r-1 - S_r|^2 less the noise difference (nested least squares): keep r while
    |S_r-1 - S_r|^2 > k (n_r^2 - n_r-1^2), else step down (from r_cv, or the rule's pick)."""
    info = {}
    rec = recommend(c, info=info)
    if not rec:
        return 0
    fits, s = c["fits"], info["scale"]
    r = info["rcv"] if start == "cv" else rec
    while r > 1:
        f, g = fits[r], fits[r - 1]
        if not admissible(g, DEFAULT, s):
            break
        nr = (noise_contrast(f)[0] * s) ** 2
        ng = (noise_contrast(g)[0] * s) ** 2 if r > 2 else 0
        if dist2(g["S"], r - 1, f["S"], r) > k * (nr - ng):
            break
        r -= 1
    return r


def expected_in_se_set(c, k, w):
    """Among the admissible r whose leave-one-out chi2 is within k standard errors of the
    smallest, the smallest expected error (fit_map_expected_error)."""
    fits, s = c["fits"], scatter_min(c["fits"])
    adm = [r for r in sorted(fits) if admissible(fits[r], DEFAULT, s)]
    if not adm:
        return 0
    rcv = min(adm, key=lambda r: (fits[r]["cv_chi2"], r))
    se = loo_se(fits[rcv])
    se = se if math.isfinite(se) else 0
    cand = [r for r in adm if fits[r]["cv_chi2"] <= fits[rcv]["cv_chi2"] + k * se]
    e = {r: expected(fits[r], s, w) for r in cand}
    e = {r: v if math.isfinite(v) else math.inf for r, v in e.items()}
    return min(cand, key=lambda r: (e[r], r)) if min(e.values()) < math.inf else rcv


def scale_floor(fl):
    return lambda fits: max(scatter_min(fits), math.sqrt(fl))


def scale_raised(k):
    """The smallest reduced chi2 raised by k of its own standard error, sqrt(2 / dof)."""
    def s(fits):
        v = [(f["chi2_red"], f["n_used"] - f["params"]) for f in fits.values()
             if f["S"] is not None and f["n_used"] - f["params"] >= 0.25 * f["n_used"]]
        if not v:
            return 1
        c, dof = min(v)
        return math.sqrt(c * (1 + k * math.sqrt(2 / dof))) if c > 0 else 1
    return s


def scale_finest(fits):
    """The reduced chi2 of the finest fit with dof >= N/4 (not the smallest)."""
    v = [r for r, f in fits.items()
         if f["S"] is not None and f["n_used"] - f["params"] >= 0.25 * f["n_used"]]
    return math.sqrt(fits[max(v)]["chi2_red"]) if v else 1


def candidates(with_sim):
    c = {"fit_recommend (current)": lambda k: recommend(k)}
    if with_sim:  # computed by the bench (--simcheck): it refits, the dump cannot
        for i, name in enumerate(("down", "up", "down, else up")):
            c[f"simulation-based check (bench), {name}"] = (lambda i: lambda k: k["sim"][i])(i)
    c["leave-one-out alone"] = lambda k: pick_min(k, lambda f: f["cv_chi2"])
    c["GCV alone"] = lambda k: pick_min(k, gcv)
    c["without the one-SE step"] = lambda k: recommend(k, dict(DEFAULT, one_se=0))
    c["one-SE guard kept for divisors"] = lambda k: recommend(k, dict(DEFAULT, nested=0))
    for ref in ("next", "max"):
        for w in (1, 2):
            c[f"risk vs richer map ({ref}), w={w}"] = (
                lambda ref, w: lambda k: risk_vs_richer(k, ref, w))(ref, w)
    for st in ("cv", "rec"):
        for kk in (1, 2, 3):
            c[f"self-consistency from {st}, k={kk}"] = (
                lambda st, kk: lambda k: self_consistency(k, st, kk))(st, kk)
    for kk in (0.5, 1, 2):
        for w in (1, 2):
            c[f"min expected error in {kk}-SE set, w={w}"] = (
                lambda kk, w: lambda k: expected_in_se_set(k, kk, w))(kk, w)
    c["scatter = noise model (1)"] = lambda k: recommend(k, scale_fn=lambda fits: 1.0)
    for fl in (0.8, 1):
        c[f"scatter^2 floor {fl}"] = (lambda fl: lambda k: recommend(
            k, scale_fn=scale_floor(fl)))(fl)
    for kk in (0.25, 0.5, 1):
        c[f"scatter^2 raised by {kk} SE"] = (lambda kk: lambda k: recommend(
            k, scale_fn=scale_raised(kk)))(kk)
    c["scatter from the finest fit"] = lambda k: recommend(k, scale_fn=scale_finest)
    for key, vals in (("w", (1, 1.5, 2.5, 3)), ("coarse", (1.3, 1.7, 2)), ("near", (0, 1.1, 1.2)),
                      ("esc", (0, 1.5, 2)), ("ntc", (0.2, 0.3)), ("one_se", (0.5, 2))):
        for v in vals:
            c[f"setting {key}={v}"] = (lambda key, v: lambda k: recommend(
                k, dict(DEFAULT, **{key: v})))(key, v)
    return c


def printed_picks(path):
    """(scene, raster, flux, seed) -> the recommended r the bench printed."""
    d = {}
    for line in open(path):
        t = line.split()
        if len(t) > 12 and t[6] == "|" and t[1] + " " + t[2] in RASTERS:
            d[(t[0], RASTERS.index(t[1] + " " + t[2]), float(t[3]), int(t[4]))] = int(t[10])
    return d


def main(argv):
    lo, hi, checks, dumps = 1, 15, [], []
    i = 0
    while i < len(argv):
        if argv[i] == "--tune-seeds" and i + 1 < len(argv):
            lo, hi = (int(x) for x in argv[i + 1].split("-"))
            i += 2
        elif argv[i] == "--check" and i + 1 < len(argv):
            checks.append(argv[i + 1])
            i += 2
        else:
            dumps.append(argv[i])
            i += 1
    if not dumps:
        print(__doc__, file=sys.stderr)
        return 2
    cases = [c for d in dumps for c in load(d)]
    for d, out in zip(dumps, checks):
        p, bad = printed_picks(out), 0
        for c in load(d):
            k = (c["scene"], c["raster"], c["flux"], c["seed"])
            if k in p and recommend(c) != p[k]:
                bad += 1
                print("replay differs:", k, recommend(c), p[k])
        print(f"check {d} against {out}: {len(p)} cases, {bad} differ")
        if bad:
            return 1
    tune = [c for c in cases if lo <= c["seed"] <= hi]
    held = [c for c in cases if not lo <= c["seed"] <= hi]
    print(f"cases within {OK_RATIO}x of the best r in hindsight (worst ratio): tuning seeds "
          f"{lo}-{hi} ({len(tune)} cases), held out ({len(held)}), all ({len(cases)})")

    def score(cs, fn):
        q = [ratio(c, fn(c)) for c in cs]
        return f"{sum(x <= OK_RATIO for x in q):4d} ({max(q, default=1):6.2f}x)"
    for name, fn in candidates(all(c["sim"] for c in cases)).items():
        print(f"{name:42s} {score(tune, fn)}  {score(held, fn)}  {score(cases, fn)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
