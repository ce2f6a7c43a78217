"""stage_scan.py: the checks of ipsd --bench sim on an emulated stage controller that every stage
protocol family shares (test_server_stage.py: gcs; test_server_zaber.py: zaber): bad --stage
strings exit 2 with one line naming --stage; a stage that does not answer stops ipsd at start,
naming --stage; on the emulator (powered on unreferenced) ipsd prepares the axes at start, a
small scan runs to done with every point exactly once and every stored stage position one the
stage was sent (the emulator's own log of the moves it received is the independent record); a
connection dropped mid-scan fails the scan with the stage's error, and the scan resumed on the
reconnected stage completes. What differs by family (the emulator, its options, the stage
string, how its log names a move, the microstep grid) is a Family's."""
import os
import subprocess
import sys
from dataclasses import dataclass
from typing import Callable, Sequence

import ipsd_http
from ipsd_http import Db, Ipsd

RASTER = {"area_px": 1, "step_um": 0.6, "sub_px": 3, "frames": 1}  # 11 x 11 points on 6 um
TOTAL = 121


@dataclass
class Family:
    emulator: str  # the emulator script's path
    emu_opts: Sequence[str]  # options every run of it takes
    url: Callable[[int], str]  # the --stage string for the emulator's TCP port
    bad: Sequence[str]  # --stage strings of the family that are wrong
    scan_opts: Sequence[str]  # the emulator's options for the scan: unreferenced, a drop
    started: Callable[[str], bool]  # the emulator's log: ipsd prepared the axes at start
    started_says: str
    sensor: dict  # the sensor to create
    far: Callable[[list, str], list]  # stored (x, y) positions not sent, given the log
    grid_digits: int  # decimals of um that tell raster columns apart
    span_tol_um: float  # the raster's 6 um span, to the stage's resolution


class Emulator:
    """The family's emulator --tcp 0 --verbose with opts; its command log in a file."""

    def __init__(self, fam, tmp, name, *opts):
        self.log = os.path.join(tmp, name + ".log")
        with open(self.log, "w") as log:
            self.proc = subprocess.Popen([sys.executable, "-B", fam.emulator, "--tcp", "0",
                                          "--verbose", *fam.emu_opts, *opts],
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                         stderr=log, text=True)
        self.port = int(self.proc.stdout.readline().split()[1])
        self.url = fam.url(self.port)

    def log_text(self):
        with open(self.log) as f:
            return f.read()

    def stop(self):
        self.proc.stdin.close()  # the emulator exits at the end of its stdin
        self.proc.wait(ipsd_http.DEADLINE_S)


def run(c, t, argv, daemons, fam):
    exe = argv[1]
    for bad in fam.bad:
        r = subprocess.run([exe, "--stage", bad], stderr=subprocess.PIPE,
                           stdout=subprocess.DEVNULL, text=True, timeout=ipsd_http.DEADLINE_S)
        c.eq(r.returncode, 2, "--stage %s: exit 2" % bad)
        c.ok(r.stderr.count("\n") == 1 and "--stage" in r.stderr,
             "one line naming --stage: %r" % r.stderr)

    emus = []
    try:
        # nobody answers: ipsd does not start
        gone = Emulator(fam, t, "gone")
        gone.stop()
        r = subprocess.run([exe, "--listen", "127.0.0.1:0", "--db", os.path.join(t, "x.db"),
                            "--stage", gone.url], stderr=subprocess.PIPE,
                           stdout=subprocess.DEVNULL, text=True, timeout=ipsd_http.DEADLINE_S)
        c.ok(r.returncode != 0 and "--stage" in r.stderr and "refused" in r.stderr,
             "an unreachable stage stops ipsd at start: %d %r" % (r.returncode, r.stderr))

        emu = Emulator(fam, t, "scan", *fam.scan_opts)
        emus.append(emu)
        d = Ipsd(exe, t)
        daemons.append(d)
        d.start("--stage", emu.url)
        db = Db(d.db)
        c.ok(fam.started(emu.log_text()), fam.started_says)
        sensor = d.post("/api/sensors", fam.sensor).json()["id"]
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
        stored = db.all("SELECT stage_x_um, stage_y_um FROM frames WHERE scan_id = ?", scan)
        c.eq(fam.far(stored, emu.log_text()), [],
             "every stored position is one the stage was sent")
        xs = sorted({round(p[0], fam.grid_digits) for p in stored})
        c.eq(len(xs), 11, "11 raster columns")
        c.ok(abs((xs[-1] - xs[0]) - 6.0) <= fam.span_tol_um,
             "spanning one 6 um pixel: %r" % xs[:2])
        c.eq(d.stop_term(), 0, "SIGTERM: exit 0")
        db.close()
    finally:
        for e in emus:
            if e.proc.poll() is None:
                e.stop()
