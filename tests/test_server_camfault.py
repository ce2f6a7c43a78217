#!/usr/bin/env python3
"""test_server_camfault.py IPSD: camera faults. The simulated camera's fault switch is
the failpoint camera.frame (docs/server.md, "Test hooks"): `hold` makes the camera stop answering
at a given frame (it hangs until ipsd's frame timeout, --camera-timeout, ends the wait), `error`
makes one capture fail. The hold is ended by the configured timeout, not by the test: the test
only waits for the end state (no durations asserted). Checks: the scan and its job fail with the
camera's error, no job stays running, the instrument is free (the next queued scan runs to done),
the failed scan keeps its stored points and, resumed (POST /api/scans/ID/resume), completes with
every point exactly once (Python's sqlite3 as the reader); a bad --camera-timeout exits 2."""
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd

RASTER = {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}  # 961 points of 2 frames
TOTAL = 961


def test(c, t, argv, daemons):
    exe = argv[1]
    bad = subprocess.run([exe, "--camera-timeout", "-1"], stderr=subprocess.PIPE,
                         stdout=subprocess.DEVNULL, text=True, timeout=ipsd_http.DEADLINE_S)
    c.eq(bad.returncode, 2, "--camera-timeout -1: exit 2")
    c.ok("--camera-timeout" in bad.stderr, "and names the option: %r" % bad.stderr)

    d = Ipsd(exe, t)
    daemons.append(d)
    # hits count every frame since start: the camera stops answering at the 1000th (in the first
    # scan's raster: its setup takes 629 frames on this scene and seed, its raster 1922), and
    # fails at the 4000th (the second scan takes hits 1001..3551, so it is in the resumed first
    # scan's raster)
    d.start("--camera-timeout", "0.2", failpoints="camera.frame=hold@1000;camera.frame=error@4000")
    db = Db(d.db)
    sensor = d.post("/api/sensors", {"model": "IMX-C", "serial": "cam-1"}).json()["id"]

    def submit(col):
        r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": col, "row": 30},
                                  "raster": RASTER})
        c.status(r, 202, "submit scan at column %d" % col)
        return r.json()["scan"]["id"], r.json()["job"]["id"]

    def points(scan):
        return db.val("SELECT count(*) FROM frames WHERE scan_id = ?", scan)

    def exactly_once(scan):
        return db.one("SELECT count(*), count(DISTINCT point_index), min(point_index), "
                      "max(point_index) FROM frames WHERE scan_id = ?", scan) == \
            (TOTAL, TOTAL, 0, TOTAL - 1)

    s1, j1 = submit(30)
    s2, j2 = submit(31)  # queued behind the first: runs once the instrument is free
    j = d.wait_job(j1, "failed")
    c.ok(j is not None, "the scan whose camera hangs fails")
    err = (j or {}).get("error") or ""
    c.ok("simulated camera: no frame within 0.2 s" in err, "with the camera's error: %r" % err)
    sc = d.get("/api/scans/%d" % s1).json()
    c.eq((sc["state"], sc["error"]), ("failed", err), "the scan failed with the same error")
    n1 = points(s1)
    c.ok(0 < n1 < TOTAL, "it stopped mid-raster (%d points)" % n1)
    c.eq(sc["points_done"], n1, "points_done = rows")
    c.ok("scan job %d failed: simulated camera: no frame" % j1 in d.log_text(), "logged")
    c.ok(d.wait_job(j2, "done"), "the next scan runs on the freed instrument to done")
    c.ok(exactly_once(s2), "the next scan's points exactly once")
    c.ok(ipsd_http.wait_for(lambda: db.val("SELECT count(*) FROM jobs WHERE kind = 'scan' AND "
                                           "state = 'running'") == 0), "no scan job left running")
    c.status(d.get("/api/health"), 200, "health answers")

    # a capture that fails (error@100000: the resumed run's capture) fails the job with its error
    kept = [r[0] for r in db.all("SELECT hex(mean) FROM frames WHERE scan_id = ? ORDER BY "
                                 "point_index", s1)]
    r = d.post("/api/scans/%d/resume" % s1)
    c.status(r, 202, "resume the failed scan")
    j = d.wait_job(j1, "failed")
    c.ok(j and "simulated camera: capture of frame" in (j.get("error") or ""),
         "the failing capture fails the resumed job with the camera's error: %r" % (j,))
    r = d.post("/api/scans/%d/resume" % s1)
    c.status(r, 202, "resume it again")
    c.ok(d.wait_job(j1, "done"), "the resumed scan completes")
    c.ok(exactly_once(s1), "every point of the resumed scan exactly once")
    c.eq([r[0] for r in db.all("SELECT hex(mean) FROM frames WHERE scan_id = ? AND "
                               "point_index < ? ORDER BY point_index", s1, len(kept))], kept,
         "the points stored before the camera hung are kept")
    if not db.postgres:  # SQLite's own check of its file (PostgreSQL's pages are the server's)
        c.eq(db.val("PRAGMA integrity_check"), "ok", "integrity_check")
    c.eq(d.stop_term(), 0, "SIGTERM: exit 0")
    db.close()


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
