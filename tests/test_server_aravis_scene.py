#!/usr/bin/env python3
"""test_server_aravis_scene.py IPSD IPS ARV_EMULATOR GCS_EMULATOR: a whole scan through GigE
Vision. Aravis's camera emulator on 127.0.0.1 (tests/arv_emulator.c --scene paperlike) draws
each frame as the simulated bench (the paper's sensor and optics, the paperlike scene, as
--bench sim) for where the stage is at that moment: the emulated PI controller
(tests/gcs_emulator.py) that ipsd moves, whose log of MOV commands the camera emulator follows.
ipsd runs the paper's procedure through them (--bench aravis:ID --stage gcs:tcp://...: exposure,
centring, focus, then a 3 x 3 pixel raster in 0.6 um steps), stores it and fits the POI. The same
scan on --bench sim is the reference: the map through the camera must be as near the scene's
truth (ips simulate --truth, the same sub-pixel means, at each map's recommended r) as the simulated
bench's, within 50 % and 0.01 (their noise is drawn apart, so the recommended r may differ). Prints both scans' durations and the frames per second
through the emulator (figures, never asserted)."""
import json
import math
import os
import subprocess
import sys
import time

import ipsd_http
from ipsd_http import Ipsd
from test_server_aravis import Emulator, gige_lock

SERIAL = "SCENE1"
DEVICE = "Aravis-Fake-" + SERIAL
POI = (128, 128)
RASTER = {"area_px": 3, "step_um": 0.6, "sub_px": 5, "frames": 2}  # 31 x 31 points


def scan_and_fit(c, d, what):
    """Submits the scan, waits for it and for the automatic fit's calibration of the POI; returns
    (calibration, seconds of the scan job, frames of the scan)."""
    sensor = d.post("/api/sensors", {"model": "paper", "serial": what}).json()["id"]
    t0 = time.monotonic()
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": POI[0], "row": POI[1]},
                              "raster": RASTER})
    c.status(r, 202, "%s: submit the scan" % what)
    scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
    j = d.wait_job(job, "done", timeout=8 * ipsd_http.DEADLINE_S)
    c.ok(j is not None, "%s: the scan runs to done" % what)
    seconds = time.monotonic() - t0
    path = "/api/sensors/%d/pixels/%d/%d/calibration" % (sensor, POI[0], POI[1])
    cal = None

    def fitted():
        nonlocal cal
        r = d.get(path)
        cal = r.json() if r.status == 200 else None
        return cal is not None
    c.ok(ipsd_http.wait_for(fitted, timeout=4 * ipsd_http.DEADLINE_S),
         "%s: the automatic fit gives the POI a calibration" % what)
    sc = d.get("/api/scans/%d" % scan).json()
    return cal, seconds, sc


def rms_to_truth(cal, truth):
    maps = {m["r"]: m["S_normalised"] for m in truth["maps"]}
    t = maps[cal["r"]]
    return math.sqrt(sum((a - b) ** 2 for a, b in zip(cal["S"], t)) / len(t))


def test(c, t, argv, daemons):
    exe, ips, emu_exe, gcs = argv[1], argv[2], argv[3], argv[4]
    gige_lock()  # another test's emulator would take our commands
    truth_path = os.path.join(t, "truth.json")
    subprocess.run([ips, "simulate", "--scene", "paperlike", "--grid", "3", "--frames", "1",
                    "--truth", truth_path, "-o", os.path.join(t, "grid.json")],
                   stdout=subprocess.DEVNULL, check=True, timeout=ipsd_http.DEADLINE_S)
    with open(truth_path) as f:
        truth = json.load(f)

    # the reference: the simulated bench
    ref = Ipsd(exe, os.path.join(t, "sim"))
    os.makedirs(ref.tmp)
    daemons.append(ref)
    ref.start("--calibration-map", "recommended")  # r x r maps the truth file holds
    cal_sim, s_sim, _ = scan_and_fit(c, ref, "sim")
    ref.stop_term()

    # the emulated controller (its command log followed by the camera emulator) and the camera
    log_path = os.path.join(t, "gcs.log")
    with open(log_path, "w") as log:
        stage = subprocess.Popen([sys.executable, "-B", gcs, "--tcp", "0", "--verbose",
                                  "--ont-polls", "1"], stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE, stderr=log, text=True)
    emu = None
    try:
        port = int(stage.stdout.readline().split()[1])
        emu = Emulator(emu_exe, SERIAL, "--scene", "paperlike", "--gcs-log", log_path)
        d = Ipsd(exe, t)
        daemons.append(d)
        d.start("--calibration-map", "recommended", "--bench", "aravis:" + DEVICE, "--stage",
                "gcs:tcp://127.0.0.1:%d?poll_ms=1" % port)
        cal_arv, s_arv, sc = scan_and_fit(c, d, "aravis")
        d.stop_term()
    finally:
        if emu:
            emu.close()
        stage.stdin.close()
        stage.wait(ipsd_http.DEADLINE_S)

    if not (cal_sim and cal_arv):
        return
    e_sim, e_arv = rms_to_truth(cal_sim, truth), rms_to_truth(cal_arv, truth)
    c.eq((sc["setup"]["camera"]["serial"], sc["setup"]["setup"]), (SERIAL, "paper"),
         "the frames are the emulator's, after the paper's set-up")
    c.ok(e_arv <= 1.5 * e_sim + 0.01,
         "the map through GigE Vision is as near the truth as the simulated bench's: rms %.4f "
         "(sim %.4f) at r = %d" % (e_arv, e_sim, cal_arv["r"]))
    points = sc["raster"]["points_total"]
    frames = points * RASTER["frames"]
    print("figures: %d points x %d frames of %dx%d: sim bench %.1f s, GigE Vision emulator %.1f s "
          "(%.0f raster frames/s at most through the emulator, setup included); map rms to the "
          "truth: sim %.4f at r = %d, emulator %.4f at r = %d"
          % (points, RASTER["frames"], RASTER["sub_px"], RASTER["sub_px"], s_sim, s_arv,
             frames / s_arv, e_sim, cal_sim["r"], e_arv, cal_arv["r"]))


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
