#!/usr/bin/env python3
"""allpixels.py [BUILD_DIR]: pixels mapped per hour of bench time, and the fit time of every pixel
of one scan. Prints figures, never pass/fail. Standard library only.

Starts BUILD_DIR/server/ipsd (default build/) with --bench sim on a temporary database and, RUNS
times (3), scans the paper's raster (5 x 5 pixels of 6 um in 0.6 um steps, 2601 points, 9 x 9
sub-frame, FRAMES (12) frames a point, paperlike scene, a new seed each run), waits for its
automatic fit (the POI), then fits every pixel the raster covers with the automatic fit's
options (r = 1..8, the F-test of the paper's edge model, Wiener: POST /api/scans/{id}/fits with
"pixels": "all"). Times are the jobs' own (started_ms .. finished_ms in the database rows, as the
API reports them), so HTTP polling does not count:
  - scan_s: the scan job on the simulated bench (setup and raster);
  - poi_fit_s: the automatic fit of the POI; all_fit_s: the fit of every covered pixel;
  - pixels per bench hour: 3600 x pixels / (scan_s + fit time), with the POI alone (one scan,
    one map: what ipsd did before) and with every covered pixel;
  - the same per hour of a real bench's exposure time: points x frames x the exposure the scan's
    setup chose (a lower bound of a real scan's time: no stage moves, settling or readout), plus
    the fit time, which the fit workers spend while the next scan runs (so the bound is the
    exposure alone once fits overlap scans).
Environment: RUNS, FRAMES, WORKERS (ipsd --workers, 2)."""
import http.client
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUILD = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build"))
RUNS = int(os.environ.get("RUNS", 3))
FRAMES = int(os.environ.get("FRAMES", 12))
WORKERS = os.environ.get("WORKERS", "2")


def call(port, method, path, body=None):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=600)
    c.request(method, path, json.dumps(body) if body is not None else None,
              {"Content-Type": "application/json"} if body is not None else {})
    r = c.getresponse()
    data = r.read()
    c.close()
    return r.status, json.loads(data) if data else None


def wait_job(port, job):
    while True:
        _, j = call(port, "GET", "/api/jobs/%d" % job)
        if j["state"] in ("done", "failed", "cancelled"):
            return j
        time.sleep(0.05)  # a benchmark: polling does not enter the jobs' own times


def secs(j):
    return (j["finished_ms"] - j["started_ms"]) / 1000.0


def main():
    tmp = tempfile.mkdtemp(prefix="ipsd-allpixels-")
    port_file = os.path.join(tmp, "port")
    proc = subprocess.Popen([os.path.join(BUILD, "server", "ipsd"), "--listen", "127.0.0.1:0",
                             "--port-file", port_file, "--db", os.path.join(tmp, "ipsd.db"),
                             "--workers", WORKERS, "--access-log", "off"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        while not (os.path.exists(port_file) and open(port_file).read().strip()):
            time.sleep(0.02)
        port = int(open(port_file).read())
        _, sn = call(port, "POST", "/api/sensors", {"model": "bench", "serial": "allpixels"})
        rows = []
        for run in range(RUNS):
            st, r = call(port, "POST", "/api/scans",
                         {"sensor_id": sn["id"], "poi": {"col": 40 + 10 * run, "row": 60},
                          "raster": {"area_px": 5, "step_um": 0.6, "sub_px": 9,
                                     "frames": FRAMES}, "scene": "paperlike", "seed": run + 1})
            scan = wait_job(port, r["job"]["id"])
            _, jobs = call(port, "GET", "/api/jobs?kind=fit&scan=%d" % r["scan"]["id"])
            auto = wait_job(port, jobs["items"][0]["id"])
            _, sc = call(port, "GET", "/api/scans/%d" % r["scan"]["id"])
            _, cov = call(port, "GET", "/api/scans/%d/coverage" % r["scan"]["id"])
            st, fa = call(port, "POST", "/api/scans/%d/fits" % r["scan"]["id"],
                          {"pixels": "all", "ftest": "top,left,bottom", "wiener": True})
            allj = wait_job(port, fa["job"]["id"])
            exposure_s = (sc["raster"]["points_total"] * FRAMES * sc["setup"]["exposure_us"] / 1e6)
            rows.append({"scan_s": secs(scan), "poi_fit_s": secs(auto), "all_fit_s": secs(allj),
                         "pixels": allj["points_done"], "covered": cov["covered"],
                         "points": sc["raster"]["points_total"], "exposure_s": exposure_s,
                         "state": allj["state"]})
        print("ipsd --bench sim --workers %s, the paper's raster (5 x 5 px, 0.6 um, 9 x 9 "
              "sub-frame, %d frames), %d runs" % (WORKERS, FRAMES, RUNS))
        print("%4s %8s %8s %9s %9s %7s %10s %13s %13s %11s" %
              ("run", "points", "scan_s", "poi_fit_s", "all_fit_s", "pixels", "ms/pixel",
               "px/h POI only", "px/h all", "exposure_s"))
        for i, r in enumerate(rows):
            one = 3600 / (r["scan_s"] + r["poi_fit_s"])
            allph = 3600 * r["pixels"] / (r["scan_s"] + r["all_fit_s"])
            print("%4d %8d %8.2f %9.3f %9.3f %7d %10.1f %13.0f %13.0f %11.1f" %
                  (i + 1, r["points"], r["scan_s"], r["poi_fit_s"], r["all_fit_s"], r["pixels"],
                   1000 * r["all_fit_s"] / max(r["pixels"], 1), one, allph, r["exposure_s"]))
        med = sorted(rows, key=lambda r: r["all_fit_s"])[len(rows) // 2]
        print("median: all %d covered pixels fitted in %.2f s (%.0f ms a pixel; the POI's "
              "automatic fit %.0f ms)" % (med["pixels"], med["all_fit_s"],
                                          1000 * med["all_fit_s"] / med["pixels"],
                                          1000 * med["poi_fit_s"]))
        print("simulated bench: %.0f pixels per bench hour (POI only: %.0f)" %
              (3600 * med["pixels"] / (med["scan_s"] + med["all_fit_s"]),
               3600 / (med["scan_s"] + med["poi_fit_s"])))
        print("a real bench, exposure-limited (%.0f s of exposure a scan): %.0f pixels per hour "
              "with the fits after the scan, %.0f with the fits overlapping the next scan "
              "(POI only: %.1f)" %
              (med["exposure_s"], 3600 * med["pixels"] / (med["exposure_s"] + med["all_fit_s"]),
               3600 * med["pixels"] / med["exposure_s"], 3600 / med["exposure_s"]))
    finally:
        proc.terminate()
        proc.wait()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
