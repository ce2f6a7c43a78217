#!/usr/bin/env python3
"""test_server_sched.py IPSD: the scheduler options of ipsd's threads (docs/operations.md, "Reads
while fits run"), read back from the kernel's own view of each thread (/proc/PID/task/TID/stat
field 19 the nice value, .../sched the policy and, Linux 6.12+, the slice): --fit-nice N puts
the --workers fit worker threads, and only them, at nice N; --fit-batch makes them SCHED_BATCH
(3), --fit-sched idle SCHED_IDLE (5); --http-slice-us gives an HTTP thread that served a request
that slice (where the kernel shows slices; an older kernel refuses it, logged, and the check is
skipped); --http-nice -5 puts it at nice -5 (where this process may lower a nice value; refused,
it is logged and stays at 0). Out-of-range values stop ipsd at start with exit 2 naming the
option."""
import os
import re
import subprocess
import sys

import ipsd_http
from ipsd_http import Ipsd


def threads(pid):
    """(name, nice, policy, slice_ns or None) of each of the process's threads."""
    out = []
    for tid in os.listdir("/proc/%d/task" % pid):
        base = "/proc/%d/task/%s/" % (pid, tid)
        try:
            stat = open(base + "stat").read()
            sched = open(base + "sched").read()
            name = open(base + "comm").read().strip()
        except OSError:
            continue  # a thread that ended meanwhile
        nice = int(stat[stat.rindex(")") + 2:].split()[16])  # field 19 (after pid and comm)
        pol = re.search(r"^policy\s*:\s*(\d+)", sched, re.M)
        sl = re.search(r"^se\.slice\s*:\s*(\d+)", sched, re.M)
        out.append((name, nice, int(pol.group(1)) if pol else None, int(sl.group(1)) if sl else None))
    return out


def test(c, t, argv, daemons):
    d = Ipsd(argv[1], t)
    daemons.append(d)
    if not sys.platform.startswith("linux"):
        c.ok(True, "not Linux: the thread scheduler options are not checked")
        return
    d.start("--workers", "3", "--http-threads", "1", "--fit-nice", "15", "--fit-batch",
            "--http-slice-us", "200")
    c.status(d.get("/api/health"), 200, "a request: the one HTTP thread sets its slice")
    # each worker lowers itself as it starts: wait until the three have
    ipsd_http.wait_for(lambda: len([x for x in threads(d.proc.pid) if x[1] == 15]) >= 3)
    th = threads(d.proc.pid)
    fit = [x for x in th if x[1] == 15]
    c.eq(len(fit), 3, "three threads at nice 15, the three fit workers: %r" % th)
    c.ok(all(x[2] == 3 for x in fit), "they run SCHED_BATCH (policy 3)")
    c.ok(all(x[1] == 0 and x[2] == 0 for x in th if x[1] != 15),
         "every other thread at nice 0, SCHED_OTHER")
    http = [x for x in th if x[0].startswith("MHD")]
    c.eq(len(http), 1, "one HTTP pool thread")
    refused = "refused a 200 us slice" in d.log_text()
    if http and http[0][3] is not None and not refused:
        c.eq(http[0][3], 200000, "the HTTP thread's slice: 200 us")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")

    # SCHED_IDLE fit workers (the policy alone decides their weight: the kernel shows nice 0)
    # and HTTP threads at a negative nice
    d.start("--workers", "2", "--http-threads", "1", "--fit-sched", "idle", "--http-nice", "-5")
    c.status(d.get("/api/health"), 200, "a request: the HTTP thread sets its nice")
    ipsd_http.wait_for(lambda: len([x for x in threads(d.proc.pid) if x[2] == 5]) >= 2)
    th = threads(d.proc.pid)
    c.eq(len([x for x in th if x[2] == 5]), 2,
         "the two fit workers, and only they, run SCHED_IDLE (policy 5): %r" % th)
    http = [x for x in th if x[0].startswith("MHD")]
    if "nice -5 refused" in d.log_text():
        c.ok(http and http[0][1] == 0, "nice -5 refused (logged): the HTTP thread stays at 0")
    else:
        c.ok(http and http[0][1] == -5 and http[0][2] == 0,
             "the HTTP thread at nice -5, SCHED_OTHER: %r" % http)
    c.ok(all(x[1] == 0 and x[2] == 0 for x in th if x[2] != 5 and not x[0].startswith("MHD")),
         "every other thread at nice 0, SCHED_OTHER")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")

    d.start("--workers", "1")
    ipsd_http.wait_for(lambda: any(x[1] != 0 for x in threads(d.proc.pid)))
    th = threads(d.proc.pid)
    c.eq(sorted(x[1] for x in th if x[1] != 0), [10], "by default the one fit worker at nice 10")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")

    for flag, bad in (("--fit-nice", "20"), ("--fit-nice", "-1"), ("--http-slice-us", "50"),
                      ("--http-slice-us", "100001"), ("--fit-sched", "fifo"),
                      ("--http-nice", "-21"), ("--http-nice", "20")):
        p = subprocess.run([argv[1], "--db", d.db, flag, bad], stderr=subprocess.PIPE,
                           stdout=subprocess.DEVNULL, text=True, timeout=ipsd_http.DEADLINE_S)
        c.ok(p.returncode == 2 and flag in p.stderr, "%s %s refused: %r" % (flag, bad, p.stderr))


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
