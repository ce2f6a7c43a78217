"""fitdoc.py: what of an `ips fit` document (or a stored fit's, the same document) may differ
between two runs of the same fit: the wall times, and nothing else (docs/contracts.md). The tests
that compare documents number for number strip them with untimed(). And rms_vs_truth, a map's
error against the simulator's truth (`ips simulate --truth`), as the fidelity harness measures."""
import math

TIMES = {"timing_ms", "design_ms", "solve_ms"}


def untimed(d):
    """d without the TIMES keys at any depth (a new object; d is left as it was)."""
    if isinstance(d, dict):
        return {k: untimed(v) for k, v in d.items() if k not in TIMES}
    if isinstance(d, list):
        return [untimed(x) for x in d]
    return d


def rms_vs_truth(S, r, T, m, g=240):
    """rms over the pixel of two mean-1 piecewise-constant maps (r x r and m x m, row-major y then
    x) sampled at the centres of a g x g grid (instrument/fidelity.c's fid_map_rms)."""
    ms, mt = sum(S) / len(S), sum(T) / len(T)
    acc = 0.0
    for j in range(g):
        for i in range(g):
            u, v = (i + 0.5) / g, (j + 0.5) / g
            d = S[int(v * r) * r + int(u * r)] / ms - T[int(v * m) * m + int(u * m)] / mt
            acc += d * d
    return math.sqrt(acc / (g * g))
