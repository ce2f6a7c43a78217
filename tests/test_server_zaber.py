#!/usr/bin/env python3
"""test_server_zaber.py IPSD: ipsd --bench sim with the second stage protocol family:
the simulated camera with the "zaber" stage backend on the emulated Zaber devices of
tests/zaber_emulator.py (TCP loopback), the way test_server_stage.py runs the "gcs" one: any camera
backend with any stage backend. Checks (tests/stage_scan.py, shared with the gcs family): bad
--stage strings of the zaber family exit 2 with one line naming --stage; devices that do not
answer stop ipsd at start; on the emulator (powered on without a reference position) ipsd homes
the axes at start, a small scan runs to done with every point exactly once, and every stored stage
position is one the devices were sent (the emulator's own log of "move abs" commands, in
microsteps of step_um, is the independent record); a connection dropped mid-scan fails the scan
with the stage's error, and the scan resumed on the reconnected stage completes."""
import os
import re
import sys

import ipsd_http
import stage_scan

EMULATOR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "zaber_emulator.py")
STEP_UM = 0.001  # a microstep of 1 nm: the raster's 0.6 um steps fall on the grid
MOVE = re.compile(r"<- '/(\d+) (\d+) move abs (-?\d+)'")


def moves_um(log, axis):
    """Every "move abs" target of device 1's axis the devices were sent, in um."""
    return {int(m.group(3)) * STEP_UM for m in MOVE.finditer(log)
            if m.group(1) == "1" and m.group(2) == str(axis)}


def far(stored, log):
    """get pos answers whole microsteps: a stored position is a sent target (to rounding)."""
    sent_x, sent_y = moves_um(log, 1), moves_um(log, 2)
    return [p for p in stored
            if not any(abs(p[0] - m) <= 1e-9 for m in sent_x)
            or not any(abs(p[1] - m) <= 1e-9 for m in sent_y)]


ZABER = stage_scan.Family(
    emulator=EMULATOR, emu_opts=["--limits=-50000000:50000000"],
    url=lambda port: "zaber:tcp://127.0.0.1:%d?step_um=%g&poll_ms=1" % (port, STEP_UM),
    bad=["zaber:tcp://stage-host:55550", "zaber:tcp://h:1?step_um=1&unit=mm",
         "zaber:serial:/dev/ttyUSB0?step_um=1&devices=1,2"],
    # axis move #300 (x, y and z each count: the 100th stage move) closes the connection
    # mid-move (a scan makes 121 raster moves and its setup more)
    scan_opts=["--unhomed", "--chatty", "--drop-after-mov", "300"],
    started=lambda log: all("<- '/1 %d home'" % a in log for a in (1, 2, 3)),
    started_says="at start ipsd homed the axes without a reference position",
    sensor={"model": "IMX-Z", "serial": "zaber-1"},
    far=far, grid_digits=6, span_tol_um=2 * STEP_UM)


def test(c, t, argv, daemons):
    stage_scan.run(c, t, argv, daemons, ZABER)


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
