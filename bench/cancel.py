#!/usr/bin/env python3
"""cancel.py [BUILD_DIR]: how long a cancel and a SIGTERM take to stop a running fit (the goal:
within a second, "between r and inside the long loops"); prints figures, never pass/fail.

Starts BUILD_DIR/server/ipsd (default build/) with one fit worker on a free loopback port and a
temporary database, and fits an uploaded scan of POINTS (2000) points at r = R (16, r_min = r_max)
with the paper's LM ("method": "lm"): first once to its end (the fit's own time), then ROUNDS (5)
times stopped after a delay that walks through the fit (a fraction of its time): by
POST /api/jobs/ID/cancel (time from the request to the job's state "cancelled") and by SIGTERM
(time from the signal to ipsd's exit). Environment: POINTS, R, ROUNDS. Standard library only."""
import http.client
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build"))
POINTS = int(os.environ.get("POINTS", 2000))
R = int(os.environ.get("R", 16))
ROUNDS = int(os.environ.get("ROUNDS", 5))


def body():
    """A 6 um pixel scanned at POINTS quasi-random places (a Gaussian response)."""
    x = [0.3 + 5.4 * ((i * 0.618034) % 1) for i in range(POINTS)]
    y = [0.3 + 5.4 * ((i * 0.414214) % 1) for i in range(POINTS)]
    s = [100 + 5000 * math.exp(-((a - 3) ** 2 + (b - 3) ** 2) / 8) for a, b in zip(x, y)]
    return {"scan": {"pitch_um": 6, "spot_radius_um": 1.342, "bias_dn": 100,
                     "gain_e_per_dn": 3.153, "read_noise_e": 5.67, "frames": 12,
                     "x_um": x, "y_um": y, "signal_dn": s},
            "r_min": R, "r_max": R, "method": "lm"}


class Server:
    def __init__(self, tmp):
        self.tmp = tmp
        self.proc = None

    def start(self):
        port_file = os.path.join(self.tmp, "port")
        if os.path.exists(port_file):
            os.remove(port_file)
        log = open(os.path.join(self.tmp, "ipsd.log"), "ab")
        self.proc = subprocess.Popen(
            [os.path.join(BUILD, "server", "ipsd"), "--listen", "127.0.0.1:0", "--port-file",
             port_file, "--db", os.path.join(self.tmp, "ipsd.db"), "--workers", "1",
             "--access-log", "off"], stdout=log, stderr=subprocess.STDOUT)
        for _ in range(400):
            if os.path.exists(port_file) and open(port_file).read().strip():
                break
            time.sleep(0.025)
        self.port = int(open(port_file).read())

    def call(self, method, path, data=None):
        """One request on a connection of its own: the waits between calls can outlast ipsd's
        idle timeout for a kept-alive connection (a fit at r = 16 by LM takes minutes)."""
        hdr = {"Content-Type": "application/json"} if data is not None else {}
        c = http.client.HTTPConnection("127.0.0.1", self.port, timeout=60)
        try:
            c.request(method, path, json.dumps(data) if data is not None else None, hdr)
            r = c.getresponse()
            return r.status, json.loads(r.read() or b"null")
        finally:
            c.close()

    def state(self, job):
        return self.call("GET", "/api/jobs/%d" % job)[1]["state"]

    def submit_running(self, data):
        """Submits a fit and waits until the worker runs it; (job id, when it started)."""
        job = self.call("POST", "/api/fits", data)[1]["job"]["id"]
        while self.state(job) != "running":
            time.sleep(0.005)
        return job, time.monotonic()

    def stop(self):
        t = time.monotonic()
        self.proc.send_signal(signal.SIGTERM)
        self.proc.wait()
        return time.monotonic() - t


def main():
    tmp = tempfile.mkdtemp(prefix="ipsd-cancel-")
    srv = Server(tmp)
    try:
        data = body()
        srv.start()
        job, t0 = srv.submit_running(data)
        while srv.state(job) not in ("done", "failed"):
            time.sleep(0.01)
        whole = time.monotonic() - t0
        print("ipsd cancel: a fit of %d points at r = %d (LM) takes %.2f s (%s) on %d CPUs, "
              "load %s" % (POINTS, R, whole, srv.state(job), os.cpu_count(),
                           open("/proc/loadavg").read().split()[0]))
        cancels = []
        for k in range(ROUNDS):
            job, t0 = srv.submit_running(data)
            time.sleep(whole * (k + 0.5) / (ROUNDS + 1))
            t = time.monotonic()
            srv.call("POST", "/api/jobs/%d/cancel" % job)
            while srv.state(job) != "cancelled":
                time.sleep(0.002)
            cancels.append(time.monotonic() - t)
        terms = []
        srv.stop()
        for k in range(ROUNDS):
            srv.start()
            job, t0 = srv.submit_running(data)
            time.sleep(whole * (k + 0.5) / (ROUNDS + 1))
            terms.append(srv.stop())
            srv.proc = None
        srv.start()  # the given-back jobs: cancel them so that the last stop is quick
        for j in srv.call("GET", "/api/jobs?kind=fit&state=queued&limit=100")[1]["items"]:
            srv.call("POST", "/api/jobs/%d/cancel" % j["id"])

        def row(name, v):
            v = sorted(v)
            print("  %-30s min %.3f  median %.3f  max %.3f s  (%d)"
                  % (name, v[0], v[len(v) // 2], v[-1], len(v)))
        row("cancel -> job cancelled", cancels)
        row("SIGTERM -> ipsd exited", terms)
    finally:
        if srv.proc and srv.proc.poll() is None:
            srv.stop()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
