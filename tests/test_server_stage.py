#!/usr/bin/env python3
"""test_server_stage.py IPSD: ipsd --bench sim with a real stage protocol (issue 12): the
simulated camera with the "gcs" stage backend on the emulated PI GCS 2.0 controller of
tests/gcs_emulator.py (TCP loopback). Checks: bad --stage strings exit 2 with one line naming
--stage; a controller that does not answer stops ipsd at start, naming --stage; on the emulator
(powered on with the servo off and the axes unreferenced) a small scan runs to done with every
point exactly once, and every stored stage position is one the controller was sent (the
emulator's own log of MOV commands, in mm, is the independent record); a connection dropped
mid-scan fails the scan with the stage's error, and the scan resumed on the reconnected stage
completes."""
import os
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd

EMULATOR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "gcs_emulator.py")
RASTER = {"area_px": 1, "step_um": 0.6, "sub_px": 3, "frames": 1}  # 11 x 11 points on 6 um
TOTAL = 121


class Emulator:
    """gcs_emulator.py --tcp 0 with opts; its command log (--verbose) in a file."""

    def __init__(self, tmp, name, *opts):
        self.log = os.path.join(tmp, name + ".log")
        with open(self.log, "w") as log:
            self.proc = subprocess.Popen([sys.executable, "-B", EMULATOR, "--tcp", "0",
                                          "--verbose", *opts],
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                         stderr=log, text=True)
        self.port = int(self.proc.stdout.readline().split()[1])

    def url(self, opts="poll_ms=1"):
        return "gcs:tcp://127.0.0.1:%d?%s" % (self.port, opts)

    def moves_um(self):
        """Every MOV target (x, y) the controller was sent, in um."""
        out = []
        with open(self.log) as f:
            for line in f:
                if "<- 'MOV " in line:
                    w = line.split("'")[1].split()
                    pos = dict(zip(w[1::2], (float(v) * 1000 for v in w[2::2])))
                    out.append((pos["1"], pos["2"]))
        return out

    def stop(self):
        self.proc.stdin.close()  # the emulator exits at the end of its stdin
        self.proc.wait(ipsd_http.DEADLINE_S)


def test(c, t, argv, daemons):
    exe = argv[1]
    for bad in ("gcs:tcp://stage-host", "gcs:tcp://h:1?unit=nm", "pi:tcp://h:1"):
        r = subprocess.run([exe, "--stage", bad], stderr=subprocess.PIPE,
                           stdout=subprocess.DEVNULL, text=True, timeout=ipsd_http.DEADLINE_S)
        c.eq(r.returncode, 2, "--stage %s: exit 2" % bad)
        c.ok(r.stderr.count("\n") == 1 and "--stage" in r.stderr,
             "one line naming --stage: %r" % r.stderr)

    emus = []
    try:
        # nobody answers: ipsd does not start
        gone = Emulator(t, "gone")
        url = gone.url()
        gone.stop()
        r = subprocess.run([exe, "--listen", "127.0.0.1:0", "--db", os.path.join(t, "x.db"),
                            "--stage", url], stderr=subprocess.PIPE, stdout=subprocess.DEVNULL,
                           text=True, timeout=ipsd_http.DEADLINE_S)
        c.ok(r.returncode != 0 and "--stage" in r.stderr and "refused" in r.stderr,
             "an unreachable controller stops ipsd at start: %d %r" % (r.returncode, r.stderr))

        # the scan; MOV #100 closes the connection mid-move (a scan makes 121 raster moves and its
        # setup more)
        emu = Emulator(t, "gcs", "--servo-off", "--unreferenced", "--drop-after-mov", "100")
        emus.append(emu)
        d = Ipsd(exe, t)
        daemons.append(d)
        d.start("--stage", emu.url())
        db = Db(d.db)
        with open(emu.log) as f:
            log = f.read()
        c.ok("<- 'SVO 1 1 2 1 3 1'" in log and "<- 'FRF 1 2 3'" in log,
             "at start ipsd switched the servos on and referenced the axes")
        sensor = d.post("/api/sensors", {"model": "IMX-G", "serial": "gcs-1"}).json()["id"]
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
        sent = emu.moves_um()
        stored = db.all("SELECT stage_x_um, stage_y_um FROM frames WHERE scan_id = ?", scan)
        # POS? answers 7 decimals of mm: a stored position is within 0.1 nm of a MOV target
        far = [p for p in stored
               if not any(abs(p[0] - m[0]) <= 1e-4 and abs(p[1] - m[1]) <= 1e-4 for m in sent)]
        c.eq(far, [], "every stored position is one the controller was sent")
        xs = sorted({round(p[0], 4) for p in stored})
        c.eq(len(xs), 11, "11 raster columns")
        c.ok(abs((xs[-1] - xs[0]) - 6.0) < 1e-3, "spanning one 6 um pixel: %r" % xs[:2])
        c.eq(d.stop_term(), 0, "SIGTERM: exit 0")
        db.close()
    finally:
        for e in emus:
            if e.proc.poll() is None:
                e.stop()


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
