"""oklines.py: the checks of the command-line tests (test_fit_*.py), one line each on stdout
("ok   ..." or "FAIL ..."), counted; finish() prints the count of failures and gives the exit
status. (The server tests count theirs with ipsd_http.Checks.)"""
import sys

_fails = [0]


def check(cond, msg):
    """Prints msg as passed or failed and counts it; returns cond."""
    print(("ok   " if cond else "FAIL ") + msg)
    _fails[0] += 0 if cond else 1
    return cond


def fails():
    return _fails[0]


def finish(prefix=""):
    """Prints the number failed and exits 1 if any failed, else 0."""
    print("%s%d failed" % (prefix, _fails[0]))
    sys.exit(1 if _fails[0] else 0)
