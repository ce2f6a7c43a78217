#!/usr/bin/env python3
"""test_server_zaber.py IPSD: ipsd --bench sim with the second stage protocol family (issue 12):
the simulated camera with the "zaber" stage backend on the emulated Zaber devices of
tests/zaber_emulator.py (TCP loopback), the way test_server_stage.py runs the "gcs" one: any camera
backend with any stage backend. Checks: bad --stage strings of the zaber family exit 2 with one
line naming --stage; devices that do not answer stop ipsd at start; on the emulator (powered on
without a reference position) ipsd homes the axes at start, a small scan runs to done with every
point exactly once, and every stored stage position is one the devices were sent (the emulator's
own log of "move abs" commands, in microsteps of step_um, is the independent record); a
connection dropped mid-scan fails the scan with the stage's error, and the scan resumed on the
reconnected stage completes."""
import os
import re
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd

EMULATOR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "zaber_emulator.py")
RASTER = {"area_px": 1, "step_um": 0.6, "sub_px": 3, "frames": 1}  # 11 x 11 points on 6 um
TOTAL = 121
STEP_UM = 0.001  # a microstep of 1 nm: the raster's 0.6 um steps fall on the grid
MOVE = re.compile(r"<- '/(\d+) (\d+) move abs (-?\d+)'")


class Emulator:
    """zaber_emulator.py --tcp 0 with opts; its command log (--verbose) in a file."""

    def __init__(self, tmp, name, *opts):
        self.log = os.path.join(tmp, name + ".log")
        with open(self.log, "w") as log:
            self.proc = subprocess.Popen([sys.executable, "-B", EMULATOR, "--tcp", "0",
                                          "--verbose", "--limits=-50000000:50000000", *opts],
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                         stderr=log, text=True)
        self.port = int(self.proc.stdout.readline().split()[1])

    def url(self, opts="poll_ms=1"):
        return "zaber:tcp://127.0.0.1:%d?step_um=%g&%s" % (self.port, STEP_UM, opts)

    def moves_um(self, axis):
        """Every "move abs" target of device 1's axis the devices were sent, in um."""
        with open(self.log) as f:
            return {int(m.group(3)) * STEP_UM for m in MOVE.finditer(f.read())
                    if m.group(1) == "1" and m.group(2) == str(axis)}

    def stop(self):
        self.proc.stdin.close()  # the emulator exits at the end of its stdin
        self.proc.wait(ipsd_http.DEADLINE_S)


def test(c, t, argv, daemons):
    exe = argv[1]
    for bad in ("zaber:tcp://stage-host:55550", "zaber:tcp://h:1?step_um=1&unit=mm",
                "zaber:serial:/dev/ttyUSB0?step_um=1&devices=1,2"):
        r = subprocess.run([exe, "--stage", bad], stderr=subprocess.PIPE,
                           stdout=subprocess.DEVNULL, text=True, timeout=ipsd_http.DEADLINE_S)
        c.eq(r.returncode, 2, "--stage %s: exit 2" % bad)
        c.ok(r.stderr.count("\n") == 1 and "--stage" in r.stderr,
             "one line naming --stage: %r" % r.stderr)

    emus = []
    try:
        gone = Emulator(t, "gone")
        url = gone.url()
        gone.stop()
        r = subprocess.run([exe, "--listen", "127.0.0.1:0", "--db", os.path.join(t, "x.db"),
                            "--stage", url], stderr=subprocess.PIPE, stdout=subprocess.DEVNULL,
                           text=True, timeout=ipsd_http.DEADLINE_S)
        c.ok(r.returncode != 0 and "--stage" in r.stderr and "refused" in r.stderr,
             "unreachable devices stop ipsd at start: %d %r" % (r.returncode, r.stderr))

        # the scan; axis move #300 (x, y and z each count: the 100th stage move) closes the
        # connection mid-move (a scan makes 121 raster moves and its setup more)
        emu = Emulator(t, "zaber", "--unhomed", "--chatty", "--drop-after-mov", "300")
        emus.append(emu)
        d = Ipsd(exe, t)
        daemons.append(d)
        d.start("--stage", emu.url())
        db = Db(d.db)
        with open(emu.log) as f:
            log = f.read()
        c.ok(all("<- '/1 %d home'" % a in log for a in (1, 2, 3)),
             "at start ipsd homed the axes without a reference position")
        sensor = d.post("/api/sensors", {"model": "IMX-Z", "serial": "zaber-1"}).json()["id"]
        r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 30, "row": 30},
                                  "raster": RASTER, "seed": 3})
        c.status(r, 202, "submit a scan")
        scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
        j = d.wait_job(job, "failed")
        err = (j or {}).get("error") or ""
        c.ok("connection closed by the controller" in err,
             "the dropped connection fails the scan with the stage's error: %r" % err)
        r = d.post("/api/scans/%d/resume" % scan)
        c.status(r, 202, "resume the scan")
        c.ok(d.wait_job(job, "done", timeout=4 * ipsd_http.DEADLINE_S),
             "the resumed scan on the reconnected stage runs to done")
        c.eq(db.one("SELECT count(*), count(DISTINCT point_index), min(point_index), "
                    "max(point_index) FROM frames WHERE scan_id = ?", scan),
             (TOTAL, TOTAL, 0, TOTAL - 1), "every point exactly once")
        sent_x, sent_y = emu.moves_um(1), emu.moves_um(2)
        stored = db.all("SELECT stage_x_um, stage_y_um FROM frames WHERE scan_id = ?", scan)
        # get pos answers whole microsteps: a stored position is a sent target (to rounding)
        far = [p for p in stored
               if not any(abs(p[0] - m) <= 1e-9 for m in sent_x)
               or not any(abs(p[1] - m) <= 1e-9 for m in sent_y)]
        c.eq(far, [], "every stored position is one the devices were sent")
        xs = sorted({round(p[0], 6) for p in stored})
        c.eq(len(xs), 11, "11 raster columns")
        c.ok(abs((xs[-1] - xs[0]) - 6.0) <= 2 * STEP_UM, "spanning one 6 um pixel: %r" % xs[:2])
        c.eq(d.stop_term(), 0, "SIGTERM: exit 0")
        db.close()
    finally:
        for e in emus:
            if e.proc.poll() is None:
                e.stop()


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
