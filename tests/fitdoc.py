"""fitdoc.py: what of an `ips fit` document (or a stored fit's, the same document) may differ
between two runs of the same fit: the wall times, and nothing else (docs/contracts.md). The tests
that compare documents number for number strip them with untimed()."""

TIMES = {"timing_ms", "design_ms", "solve_ms"}


def untimed(d):
    """d without the TIMES keys at any depth (a new object; d is left as it was)."""
    if isinstance(d, dict):
        return {k: untimed(v) for k, v in d.items() if k not in TIMES}
    if isinstance(d, list):
        return [untimed(x) for x in d]
    return d
