#!/usr/bin/env python3
"""soak.py [BUILD_DIR]: a bounded soak of ipsd (prints figures, never pass/fail).

Starts BUILD_DIR/server/ipsd (default build/) on a free loopback port with a temporary database
and runs, for DURATION seconds (60) or REQUESTS requests (200000), whichever comes first:
  - READERS (4) threads reading: the sensor list, a sensor, the scan list, the calibration of a
    pixel (JSON and CSV), the calibration search, a fit document, the health check;
  - one writer thread creating sensors;
  - one thread submitting fits of an uploaded 9 x 9 scan (`ips simulate`) that each become a
    pixel's calibration, at most FITS (400).
It samples ipsd's resident memory (VmRSS) every second and prints it at the start, the middle and
the end of the load and after IDLE seconds (10) of no requests, with request rates, error counts
and latency percentiles. Flat RSS is the goal: allocator arenas trimmed when idle.
Environment: DURATION, REQUESTS, READERS, FITS, IDLE. Standard library only."""
import http.client
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build"))
DURATION = float(os.environ.get("DURATION", 60))
REQUESTS = int(os.environ.get("REQUESTS", 200000))
READERS = int(os.environ.get("READERS", 4))
FITS = int(os.environ.get("FITS", 400))
IDLE = float(os.environ.get("IDLE", 10))


def rss_mb(pid):
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


class Stats:
    def __init__(self):
        self.lock = threading.Lock()
        self.lat = {}  # kind (read, sensor, fit) -> latencies in ms
        self.errors = {}
        self.count = 0

    def add(self, ms, status, what):
        """status 0: the request failed below HTTP (a reset or a timeout)."""
        with self.lock:
            self.count += 1
            self.lat.setdefault(what, []).append(ms)
            if (status >= 400 or status == 0) and not (status == 409 and what == "sensor"):
                key = (what, status or "socket")
                self.errors[key] = self.errors.get(key, 0) + 1


def main():
    ipsd = os.path.join(BUILD, "server", "ipsd")
    ips = os.path.join(BUILD, "cli", "ips")
    for exe in (ipsd, ips):
        if not os.access(exe, os.X_OK):
            sys.exit("soak.py: no %s (build first)" % exe)
    tmp = tempfile.mkdtemp(prefix="ipsd-soak-")
    proc = None
    try:
        scan_file = os.path.join(tmp, "scan.json")
        subprocess.run([ips, "simulate", "--grid", "9", "--seed", "3", "-o", scan_file],
                       check=True, stdout=subprocess.DEVNULL)
        with open(scan_file) as f:
            scan = json.load(f)
        # a dense scan too (29 x 29 points at 0.2 um, as bench/load.sh): bigger fits
        subprocess.run([ips, "simulate", "--grid", "29", "--step", "0.2", "--seed", "4", "-o",
                        scan_file], check=True, stdout=subprocess.DEVNULL)
        with open(scan_file) as f:
            dense = json.load(f)
        port_file = os.path.join(tmp, "port")
        log = open(os.path.join(tmp, "ipsd.log"), "wb")
        proc = subprocess.Popen([ipsd, "--listen", "127.0.0.1:0", "--port-file", port_file,
                                 "--db", os.path.join(tmp, "ipsd.db"), "--workers", "2"],
                                stdout=log, stderr=subprocess.STDOUT)
        for _ in range(200):
            if os.path.exists(port_file) and open(port_file).read().strip():
                break
            time.sleep(0.05)
        port = int(open(port_file).read())

        def conn():
            return http.client.HTTPConnection("127.0.0.1", port, timeout=60)

        def call(c, method, path, body=None):
            hdr = {"Content-Type": "application/json"} if body is not None else {}
            c.request(method, path, json.dumps(body) if body is not None else None, hdr)
            r = c.getresponse()
            data = r.read()
            return r.status, data

        c = conn()
        st, data = call(c, "POST", "/api/sensors", {"model": "SOAK", "serial": "0"})
        sensor = json.loads(data)["id"]
        fit_body = {"scan": scan, "sensor_id": sensor, "pixel": {"col": 10, "row": 10},
                    "r_max": 6, "wiener": True}
        def run_job(path, body):
            """POSTs a job and polls it to its end; the job document."""
            st, data = call(c, "POST", path, body)
            job = json.loads(data)["job"]["id"]
            while True:
                st, data = call(c, "GET", "/api/jobs/%d" % job)
                j = json.loads(data)
                if j["state"] in ("done", "failed", "cancelled"):
                    return j
                time.sleep(0.05)

        fit_id = run_job("/api/fits", fit_body)["fit_id"]
        # a scan on the simulated bench, to read its raster and frames
        scan_id = run_job("/api/scans", {"sensor_id": sensor, "poi": {"col": 100, "row": 100},
                                         "raster": {"area_px": 3, "step_um": 1.0}})["scan_id"]
        c.close()

        stats = Stats()
        stop = threading.Event()
        t0 = time.monotonic()
        reads = ["/api/sensors", "/api/sensors/%d" % sensor, "/api/scans",
                 "/api/sensors/%d/pixels/10/10/calibration" % sensor,
                 "/api/sensors/%d/pixels/10/10/calibration?format=csv" % sensor,
                 "/api/calibrations?limit=50", "/api/fits/%d" % fit_id, "/api/health",
                 "/api/scans/%d/pixels/0/0?all=1" % scan_id, "/api/scans/%d/points/40" % scan_id,
                 "/api/sensors/%d/pixels/10/10/history?limit=200" % sensor]

        def timed(c, what, method, path, body=None):
            """One request, counted; a failure below HTTP counts as an error and reconnects."""
            t = time.monotonic()
            try:
                s, data = call(c[0], method, path, body)
            except (OSError, http.client.HTTPException):
                s, data = 0, b""
                c[0].close()
                c[0] = conn()
            stats.add((time.monotonic() - t) * 1e3, s, what)
            return s, data

        def reader(k):
            c = [conn()]
            i = k
            while not stop.is_set():
                timed(c, "read", "GET", reads[i % len(reads)])
                i += 1

        def writer():
            c = [conn()]
            i = 1
            while not stop.is_set():
                timed(c, "sensor", "POST", "/api/sensors", {"model": "SOAK", "serial": str(i)})
                i += 1
                time.sleep(0.01)

        fit_jobs = []

        def fitter():
            c = [conn()]
            for i in range(FITS):
                if stop.is_set():
                    break
                body = fit_body if i % 2 else dict(fit_body, scan=dense, r_max=12)
                s, data = timed(c, "fit", "POST", "/api/fits", body)
                if s == 202:
                    fit_jobs.append(json.loads(data)["job"]["id"])
                time.sleep(0.05)

        threads = [threading.Thread(target=reader, args=(k,)) for k in range(READERS)]
        threads += [threading.Thread(target=writer), threading.Thread(target=fitter)]
        samples = [(0.0, rss_mb(proc.pid))]
        for t in threads:
            t.start()
        while time.monotonic() - t0 < DURATION and stats.count < REQUESTS:
            time.sleep(1)
            samples.append((time.monotonic() - t0, rss_mb(proc.pid)))
        stop.set()
        for t in threads:
            t.join()
        load_s = time.monotonic() - t0
        end_rss = rss_mb(proc.pid)
        time.sleep(IDLE)
        idle_rss = rss_mb(proc.pid)
        # the submitted fits' end states (a job that failed is an error too, not only a 5xx)
        c = conn()
        ends = {}
        for job in fit_jobs:
            st, data = call(c, "GET", "/api/jobs/%d" % job)
            state = json.loads(data)["state"] if st == 200 else "http %d" % st
            ends[state] = ends.get(state, 0) + 1
        c.close()

        def pct(lat, p):
            return lat[min(len(lat) - 1, int(p / 100.0 * len(lat)))] if lat else float("nan")
        mid = samples[len(samples) // 2][1]
        peak = max(r for _, r in samples)
        print("ipsd soak: %.0f s of load, %d requests (%.0f/s), %d readers, 1 writer, fits"
              % (load_s, stats.count, stats.count / load_s, READERS))
        print("  %-7s %9s %8s %8s %8s %8s" % ("kind", "requests", "per s", "p50 ms", "p99 ms",
                                              "max ms"))
        every = sorted(x for v in stats.lat.values() for x in v)
        for what, lat in sorted(stats.lat.items()) + [("all", every)]:
            lat = sorted(lat)
            print("  %-7s %9d %8.1f %8.2f %8.2f %8.1f" % (what, len(lat), len(lat) / load_s,
                                                         pct(lat, 50), pct(lat, 99), lat[-1]))
        print("  errors: %s" % (stats.errors or "none"))
        print("  fits submitted: %d; their jobs now: %s" % (len(fit_jobs), ends or "none"))
        print("  RSS MB: start %.1f  middle %.1f  end %.1f  peak %.1f  after %.0f s idle %.1f"
              % (samples[0][1], mid, end_rss, peak, IDLE, idle_rss))
        # flat: the second half of the load must not keep growing what the first half reached
        print("  RSS growth, middle to end: %+.1f MB (%+.0f %%); every 10 s: %s"
              % (end_rss - mid, 100 * (end_rss - mid) / mid,
                 " ".join("%.0f" % r for t, r in samples[::10])))
    finally:
        if proc:
            proc.terminate()
            proc.wait()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
