#!/usr/bin/env python3
"""shared.py [BUILD_DIR]: figures of ipsd on a PostgreSQL database several benches share, beside
SQLite (prints figures, never pass or fail on time).

1. Calibration reads: one pixel's current calibration (GET .../calibration, the lab's most
   frequent read, served from the reply cache) read with wrk (-c32, DURATION) from one ipsd on
   SQLite, from one ipsd on PostgreSQL, and from two ipsd on the same PostgreSQL database at once
   (one wrk each, their rates summed). Targets: PostgreSQL at least half of SQLite; two instances
   at least one.
2. Scans stored: SCANS scans of 961 points (a 3-pixel area in 0.6 um steps, the simulated bench)
   queued on one bench, then spread over four benches on one PostgreSQL database (each its own
   ipsd and simulated bench), and on one bench on SQLite: scans per minute, from the first submit
   to the last scan done. Target: four benches storing at once as fast as one each.

Starts its own throwaway PostgreSQL server (tests/pg_server.sh; Debian's postgresql) and ipsd
processes of BUILD_DIR (default build/; builds nothing). Needs wrk, psql, python3. Environment:
DURATION (10s), CONNS (32), SCANS (8, per bench)."""
import http.client
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build"))
IPSD = os.path.join(BUILD, "server", "ipsd")
DURATION = os.environ.get("DURATION", "10s")
CONNS = int(os.environ.get("CONNS", "32"))
SCANS = int(os.environ.get("SCANS", "8"))
RASTER = {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}


class Daemon:
    def __init__(self, tmp, name, db, *args):
        self.dir = os.path.join(tmp, name)
        os.makedirs(self.dir)
        port_file = os.path.join(self.dir, "port")
        self.log = open(os.path.join(self.dir, "ipsd.log"), "w")
        self.proc = subprocess.Popen([IPSD, "--listen", "127.0.0.1:0", "--port-file", port_file,
                                      "--db", db, "--access-log", "off", *args],
                                     stdout=self.log, stderr=subprocess.STDOUT)
        for _ in range(600):
            if os.path.exists(port_file) and open(port_file).read().strip():
                break
            if self.proc.poll() is not None:
                sys.exit("shared.py: ipsd did not start: " + open(self.log.name).read())
            time.sleep(0.05)
        self.port = int(open(port_file).read())
        self.conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=600)

    def call(self, method, path, body=None):
        self.conn.request(method, path, json.dumps(body) if body is not None else None,
                          {"Content-Type": "application/json"} if body is not None else {})
        r = self.conn.getresponse()
        data = r.read()
        if r.status >= 300:
            sys.exit("shared.py: %s %s -> %d %s" % (method, path, r.status, data[:300]))
        return json.loads(data)

    def wait_job(self, job):
        while self.call("GET", "/api/jobs/%d" % job)["state"] != "done":
            time.sleep(0.05)

    def stop(self):
        self.proc.terminate()
        self.proc.wait(timeout=120)
        self.log.close()


def fresh(base, schema):
    subprocess.run(["psql", "-X", "-q", "-v", "ON_ERROR_STOP=1", base, "-c",
                    "SET client_min_messages = warning; DROP SCHEMA IF EXISTS %s CASCADE; "
                    "CREATE SCHEMA %s" % (schema, schema)], check=True)
    return "%s?options=-csearch_path%%3D%s" % (base, schema)


def seed(d, scan_file):
    """A sensor and the calibration of its pixel (10, 10); the read URL."""
    sensor = d.call("POST", "/api/sensors", {"model": "LOAD", "serial": "1"})["id"]
    job = d.call("POST", "/api/fits", {"scan": scan_file, "sensor_id": sensor,
                                       "pixel": {"col": 10, "row": 10}})["job"]["id"]
    d.wait_job(job)
    return "/api/sensors/%d/pixels/10/10/calibration" % sensor


def wrk(urls):
    """Reads per second of wrk runs on urls at once (-t1 each, CONNS connections in all)."""
    procs = [subprocess.Popen(["wrk", "-t1", "-c%d" % max(1, CONNS // len(urls)), "-d" + DURATION,
                               u], stdout=subprocess.PIPE, text=True) for u in urls]
    total = 0.0
    for p in procs:
        out = p.communicate()[0]
        m = re.search(r"Requests/sec:\s+([\d.]+)", out)
        total += float(m.group(1)) if m else float("nan")
    return total


def scans_per_minute(daemons, sensor):
    """SCANS scans on each daemon at once: scans per minute, first submit to last done."""
    t0 = time.time()
    jobs = []
    for k, d in enumerate(daemons):
        for i in range(SCANS):
            r = d.call("POST", "/api/scans", {"sensor_id": sensor, "raster": RASTER,
                                              "poi": {"col": 20 + 40 * k + 4 * i, "row": 30},
                                              "seed": 100 * k + i})
            jobs.append((d, r["job"]["id"]))
    for d, j in jobs:
        d.wait_job(j)
    return len(jobs) * 60 / (time.time() - t0)


def main():
    for tool in ("wrk", "psql"):
        if not shutil.which(tool):
            sys.exit("shared.py: needs %s (scripts/deps.sh)" % tool)
    tmp = tempfile.mkdtemp(prefix="ipsd-shared-")
    pg = os.path.join(tmp, "pg")
    daemons = []
    try:
        subprocess.run(["bash", os.path.join(ROOT, "tests", "pg_server.sh"), "start", pg],
                       check=True, stdout=subprocess.DEVNULL)
        os.environ["PGPASSFILE"] = os.path.join(pg, "pgpass")
        base = open(os.path.join(pg, "uri")).read().strip()
        scan_file = json.load(open(os.path.join(ROOT, "tests", "data", "paperlike_scan.json")))
        print("ipsd %s on a %d-CPU machine; PostgreSQL %s" % (
            IPSD, os.cpu_count(), subprocess.run(["psql", "-X", "-At", base, "-c", "SHOW server_version"],
                                                 capture_output=True, text=True).stdout.strip()))

        print("== 1. calibration reads (wrk, %d connections, %s)" % (CONNS, DURATION))
        lite = Daemon(tmp, "lite", os.path.join(tmp, "ipsd.db"))
        daemons.append(lite)
        path = seed(lite, scan_file)
        r_lite = wrk(["http://127.0.0.1:%d%s" % (lite.port, path)])
        lite.stop()
        daemons.remove(lite)
        uri = fresh(base, "reads")
        a = Daemon(tmp, "pg-a", uri, "--bench-name", "a")
        daemons.append(a)
        path = seed(a, scan_file)
        r_pg = wrk(["http://127.0.0.1:%d%s" % (a.port, path)])
        b = Daemon(tmp, "pg-b", uri, "--bench-name", "b")
        daemons.append(b)
        b.call("GET", path)
        r_pg2 = wrk(["http://127.0.0.1:%d%s" % (d.port, path) for d in (a, b)])
        for d in (a, b):
            d.stop()
            daemons.remove(d)
        print("%-44s %10s" % ("", "reads/s"))
        print("%-44s %10.0f" % ("one ipsd, SQLite", r_lite))
        print("%-44s %10.0f  (%.0f %% of SQLite; target >= 50 %%)" % (
            "one ipsd, PostgreSQL", r_pg, 100 * r_pg / r_lite))
        print("%-44s %10.0f  (%.2fx one; target >= 1)" % (
            "two ipsd, one PostgreSQL database", r_pg2, r_pg2 / r_pg))

        print("== 2. scans stored (%d scans of 961 points per bench, simulated benches)" % SCANS)
        lite = Daemon(tmp, "lite2", os.path.join(tmp, "scans.db"))
        daemons.append(lite)
        sensor = lite.call("POST", "/api/sensors", {"model": "SCAN", "serial": "1"})["id"]
        s_lite = scans_per_minute([lite], sensor)
        lite.stop()
        daemons.remove(lite)
        uri = fresh(base, "scans")
        benches = [Daemon(tmp, "bench-%d" % k, uri, "--bench-name", "bench-%d" % k)
                   for k in range(4)]
        daemons.extend(benches)
        sensor = benches[0].call("POST", "/api/sensors", {"model": "SCAN", "serial": "1"})["id"]
        s_one = scans_per_minute(benches[:1], sensor)
        s_four = scans_per_minute(benches, sensor)
        for d in benches:
            d.stop()
            daemons.remove(d)
        print("%-44s %10s" % ("", "scans/min"))
        print("%-44s %10.1f" % ("one bench, SQLite", s_lite))
        print("%-44s %10.1f" % ("one bench, PostgreSQL", s_one))
        print("%-44s %10.1f  (%.2fx one bench's; target 4x: each as fast as alone)" % (
            "four benches at once, one PostgreSQL database", s_four, s_four / s_one))
    finally:
        for d in daemons:
            d.proc.kill()
        subprocess.run(["bash", os.path.join(ROOT, "tests", "pg_server.sh"), "stop", pg],
                       stdout=subprocess.DEVNULL)
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
