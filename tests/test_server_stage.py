#!/usr/bin/env python3
"""test_server_stage.py IPSD: ipsd --bench sim with a real stage protocol: the
simulated camera with the "gcs" stage backend on the emulated PI GCS 2.0 controller of
tests/gcs_emulator.py (TCP loopback). Checks (tests/stage_scan.py, shared with the zaber family):
bad --stage strings exit 2 with one line naming --stage; a controller that does not answer stops
ipsd at start, naming --stage; on the emulator (powered on with the servo off and the axes
unreferenced) ipsd switches the servos on and references the axes, a small scan runs to done with
every point exactly once, and every stored stage position is one the controller was sent (the
emulator's own log of MOV commands, in mm, is the independent record); a connection dropped
mid-scan fails the scan with the stage's error, and the scan resumed on the reconnected stage
completes."""
import math
import os
import sys

import ipsd_http
import stage_scan

EMULATOR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "gcs_emulator.py")


def moves_um(log):
    """Every MOV target (x, y) the controller was sent, in um."""
    out = []
    for line in log.splitlines():
        if "<- 'MOV " in line:
            w = line.split("'")[1].split()
            pos = dict(zip(w[1::2], (float(v) * 1000 for v in w[2::2])))
            out.append((pos["1"], pos["2"]))
    return out


def far(stored, log):
    """POS? answers 7 decimals of mm: a stored position is within 0.1 nm of a MOV target."""
    sent = moves_um(log)
    return [p for p in stored
            if not any(abs(p[0] - m[0]) <= 1e-4 and abs(p[1] - m[1]) <= 1e-4 for m in sent)]


GCS = stage_scan.Family(
    emulator=EMULATOR, emu_opts=[],
    url=lambda port: "gcs:tcp://127.0.0.1:%d?poll_ms=1" % port,
    bad=["gcs:tcp://stage-host", "gcs:tcp://h:1?unit=nm", "pi:tcp://h:1"],
    # MOV #100 closes the connection mid-move (a scan makes 121 raster moves and its setup more)
    scan_opts=["--servo-off", "--unreferenced", "--drop-after-mov", "100"],
    started=lambda log: "<- 'SVO 1 1 2 1 3 1'" in log and "<- 'FRF 1 2 3'" in log,
    started_says="at start ipsd switched the servos on and referenced the axes",
    sensor={"model": "IMX-G", "serial": "gcs-1"},
    far=far, grid_digits=4,
    span_tol_um=math.nextafter(1e-3, 0))  # within less than 1 nm


def test(c, t, argv, daemons):
    stage_scan.run(c, t, argv, daemons, GCS)


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
