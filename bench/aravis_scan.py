#!/usr/bin/env python3
"""aravis_scan.py [BUILD_DIR]: the paper's scan through a GigE Vision camera against the simulated
bench. Prints figures; never fails on time.

Runs the same scan (the defaults: 51 x 51 points, 12 frames of 9 x 9 a point, with the paper's
set-up) on three benches, each an ipsd on a temporary database, and prints each scan's duration
(POST to done) and frames per second:
  1. --bench sim (the simulated bench, its own stage);
  2. --bench sim --stage gcs:tcp://... (the emulated PI controller, tests/gcs_emulator.py);
  3. --bench aravis:ID --stage gcs:tcp://...: Aravis's GigE Vision camera emulator on 127.0.0.1
     (BUILD_DIR/tests/arv_emulator --scene paperlike) drawing the simulated bench where the
     controller is, as tests/test_server_aravis_scene.py does.
Environment: AREA, STEP, SUB, FRAMES (the raster; default the paper's). Needs a build with the
Aravis module (Debian's libaravis-dev) and the GigE Vision port 3956 of 127.0.0.1 free."""
import os
import subprocess
import sys
import tempfile
import time

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(root, "tests"))
import ipsd_http  # noqa: E402
from ipsd_http import Ipsd  # noqa: E402
from test_server_aravis import Emulator  # noqa: E402

build = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "build"))
exe = os.path.join(build, "server", "ipsd")
emu_exe = os.path.join(build, "tests", "arv_emulator")
gcs = os.path.join(root, "tests", "gcs_emulator.py")
raster = {k: t(os.environ[e]) for k, e, t in (("area_px", "AREA", int), ("step_um", "STEP", float),
                                              ("sub_px", "SUB", int), ("frames", "FRAMES", int))
          if e in os.environ}


def scan(d, what):
    sensor = d.post("/api/sensors", {"model": "paper", "serial": what}).json()["id"]
    body = {"sensor_id": sensor, "poi": {"col": 128, "row": 128}}
    if raster:
        body["raster"] = raster
    t0 = time.monotonic()
    r = d.post("/api/scans", body)
    j = d.wait_job(r.json()["job"]["id"], "done", timeout=100 * ipsd_http.DEADLINE_S)
    s = time.monotonic() - t0
    sc = d.get("/api/scans/%d" % r.json()["scan"]["id"]).json()
    ra = sc["raster"]
    frames = ra["points_total"] * ra["frames"]
    print("%-34s %s in %7.1f s: %d points x %d frames of %dx%d, %.0f raster frames/s"
          % (what, "done" if j else "NOT DONE (%s)" % sc.get("error"), s, ra["points_total"],
             ra["frames"], ra["sub_px"], ra["sub_px"], frames / s), flush=True)


def main():
    t = tempfile.mkdtemp(prefix="ipsd-bench-aravis-")
    daemons = []
    log_path = os.path.join(t, "gcs.log")
    with open(log_path, "w") as log:
        stage = subprocess.Popen([sys.executable, "-B", gcs, "--tcp", "0", "--verbose",
                                  "--ont-polls", "1"], stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE, stderr=log, text=True)
    emu = None
    try:
        url = "gcs:tcp://127.0.0.1:%s?poll_ms=1" % stage.stdout.readline().split()[1]
        emu = Emulator(emu_exe, "BENCH1", "--scene", "paperlike", "--gcs-log", log_path)
        for name, args in (("--bench sim", []), ("--bench sim --stage gcs", ["--stage", url]),
                           ("--bench aravis:ID --stage gcs", ["--bench", "aravis:" + emu.id,
                                                              "--stage", url])):
            d = Ipsd(exe, os.path.join(t, str(len(daemons))))
            os.makedirs(d.tmp)
            daemons.append(d)
            d.start(*args)
            scan(d, name)
            d.stop_term()
    finally:
        for d in daemons:
            d.cleanup()
        if emu:
            emu.close()
        stage.stdin.close()
        stage.wait(ipsd_http.DEADLINE_S)


if __name__ == "__main__":
    main()
