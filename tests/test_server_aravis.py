#!/usr/bin/env python3
"""test_server_aravis.py IPSD IPS ARV_EMULATOR: ipsd scanning through a GigE Vision camera
(--bench aravis:ID), Aravis's own camera emulator on 127.0.0.1 (tests/arv_emulator.c) drawing
its own pattern (Aravis's diagonal ramp: in Mono16 at exposure 10000 us and GainRaw 0, the pixel
at (x, y) of the frame with id F is 256 (x + y + F) mod 65535, x and y from the region's corner).

Checks: --list-cameras names the camera; a bad "setup" is refused (422, field setup), and a
sub-frame off the camera's array (422, poi.col, naming the camera); GET
/api/health says which camera and stage ipsd holds; a scan with "setup": "none" stores frames
equal to what the emulator sent, pixel for pixel (every frame the ramp, the frames of a point
consecutive frame ids: one trigger, one frame), their means, the POI's centre as given, and the
camera's provenance in the stored setup (vendor, model, serial, firmware, Mono16 at 16 bits).
The camera goes away mid-scan (the scan held at the failpoint scan.point while the emulator is
stopped): the job fails with the camera's own words, nothing stays running and ipsd answers;
resumed while another camera is on the network, it fails again (the named camera is not there;
restarted with --bench aravis, the first camera found, it is refused naming both cameras); the
camera comes back, the scan resumes (POST /api/scans/ID/resume) and completes with every point
exactly once. Python's sqlite3 reads the database (psql in the PostgreSQL run)."""
import errno
import fcntl
import socket
import struct
import subprocess
import sys
import time

import ipsd_http
from ipsd_http import Db, Ipsd

SERIAL = "PLAIN1"
DEVICE = "Aravis-Fake-" + SERIAL
POI = (40, 50)
PITCH = 6.0
RASTER = {"area_px": 1, "step_um": 2.0, "sub_px": 3, "frames": 3}  # 4 x 4 points of 3 frames
TOTAL = 16
HOLD_AT = 5  # the camera goes away after the 5th point is stored


GIGE_LOCK = "/tmp/ipsd-gige-emulator.lock"
_gige_lock_file = None


def gige_port_taken():
    """Whether a socket of another process is bound to 127.0.0.1:3956 (a bind without
    SO_REUSEADDR fails then)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(("127.0.0.1", 3956))
        except OSError as e:
            return e.errno == errno.EADDRINUSE
    return False


def gige_lock():
    """One GigE Vision emulator on 127.0.0.1 at a time across the machine, as tests/gige_lock.h
    (which says why): holds its lock file until this process ends (the whole test: it may run two
    emulators), and waits (up to 300 s) while a process that does not take it has the port."""
    global _gige_lock_file
    _gige_lock_file = open(GIGE_LOCK, "a")
    try:
        fcntl.flock(_gige_lock_file, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        print("gige_lock: another test runs a GigE Vision emulator on port 3956: waiting for it "
              "(%s)" % GIGE_LOCK, file=sys.stderr)
        fcntl.flock(_gige_lock_file, fcntl.LOCK_EX)
    if gige_port_taken():
        print("gige_lock: port 3956 of 127.0.0.1 is bound by a process without the lock: waiting "
              "for it to end", file=sys.stderr)
    deadline = time.monotonic() + 300
    while gige_port_taken() and time.monotonic() < deadline:
        time.sleep(0.1)


class Emulator:
    """tests/arv_emulator.c SERIAL [opts]: started, stopped and started again from stdin."""

    def __init__(self, exe, serial, *opts):
        self.proc = subprocess.Popen([exe, serial, *opts], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True)
        self.id = self._line().split()[1]

    def _line(self):
        return self.proc.stdout.readline().strip()

    def command(self, cmd, answer):
        self.proc.stdin.write(cmd + "\n")
        self.proc.stdin.flush()
        line = self._line()
        assert line.startswith(answer), line
        return line

    def close(self):
        self.proc.stdin.close()  # it exits at the end of its stdin
        self.proc.wait(ipsd_http.DEADLINE_S)


def ramp_ok(frame, m):
    """Whether frame (m*m values, row-major) is the emulator's ramp of some frame id."""
    v00 = frame[0]
    return all(frame[j * m + i] == (v00 + 256 * (i + j)) % 65535
               for j in range(m) for i in range(m))


def test(c, t, argv, daemons):
    exe, emu_exe = argv[1], argv[3]
    gige_lock()  # another test's emulator would take our commands
    emu = Emulator(emu_exe, SERIAL)
    try:
        run(c, t, exe, emu_exe, emu, daemons)
    finally:
        emu.close()


def run(c, t, exe, emu_exe, emu, daemons):
    c.eq(emu.id, DEVICE, "the emulator's device id")
    ls = subprocess.run([exe, "--list-cameras"], stdout=subprocess.PIPE, text=True,
                        stderr=subprocess.PIPE, timeout=ipsd_http.DEADLINE_S)
    c.eq(ls.returncode, 0, "--list-cameras exits 0")
    c.ok("aravis:%s\tAravis\tFake\t%s" % (DEVICE, SERIAL) in ls.stdout.splitlines(),
         "--list-cameras names the camera: %r" % ls.stdout)
    c.ok(ls.stdout.startswith("sim\t"), "and the simulated bench first")

    d = Ipsd(exe, t)
    daemons.append(d)
    d.start("--bench", "aravis:" + DEVICE, "--camera-timeout", "2",
            failpoints="scan.point=hold@%d" % HOLD_AT)
    h = d.get("/api/health").json()
    cam = h.get("camera") or {}
    c.eq((h.get("bench"), cam.get("backend"), cam.get("id"), cam.get("vendor"), cam.get("model"),
          cam.get("serial"), h.get("stage")),
         ("aravis:" + DEVICE, "aravis", DEVICE, "Aravis", "Fake", SERIAL, "sim"),
         "GET /api/health: the camera and the stage ipsd holds")
    db = Db(d.db)
    sensor = d.post("/api/sensors", {"model": "Fake-GV", "serial": SERIAL}).json()["id"]
    body = {"sensor_id": sensor, "poi": {"col": POI[0], "row": POI[1]}, "raster": RASTER,
            "exposure_us": 10000, "setup": "none"}
    c.error(d.post("/api/scans", dict(body, setup="quick")), 422, "setup", "a bad setup")
    c.error(d.post("/api/scans", dict(body, setup=1)), 400, "setup", "a setup not a string")
    # a sensor larger than the camera's 2048 x 2048 array: the sub-frame must lie on the camera
    big = d.post("/api/sensors", {"model": "large", "serial": "L1", "n_cols": 4096,
                                  "n_rows": 4096}).json()["id"]
    r = d.post("/api/scans", dict(body, sensor_id=big, poi={"col": 2047, "row": 50}))
    c.error(r, 422, "poi.col", "a sub-frame off the camera's array")
    c.ok("2048 x 2048" in r.text and DEVICE in r.text, "naming the camera: %r" % r.text)
    r = d.post("/api/scans", body)
    c.status(r, 202, "a scan through the camera, set up by hand")
    scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]

    # the camera goes away while the scan is held after its 5th point
    c.ok(d.wait_held("scan.point", job), "the scan holds after point %d" % HOLD_AT)
    emu.command("stop", "stopped")
    d.release("scan.point", job)
    j = d.wait_job(job, "failed")
    err = (j or {}).get("error") or ""
    c.ok(j is not None and DEVICE in err and "timeout" in err,
         "the job fails with the camera's words: %r" % err)
    sc = d.get("/api/scans/%d" % scan).json()
    c.eq((sc["state"], sc["error"]), ("failed", err), "the scan failed with the same error")
    c.eq(db.val("SELECT count(*) FROM frames WHERE scan_id = ?", scan), HOLD_AT,
         "its stored points stay")
    # (the API may read the job failed from memory before its row is written: wait for the row)
    c.ok(ipsd_http.wait_for(lambda: db.val("SELECT count(*) FROM jobs WHERE state = 'running'")
                            == 0), "nothing stays running")
    c.eq(d.get("/api/health").json().get("status"), "ok", "ipsd answers, healthy")

    # another camera on the network: not the one the bench names, and a bench that takes the
    # first camera refuses to resume on it
    other = Emulator(emu_exe, "PLAIN2")
    try:
        c.status(d.post("/api/scans/%d/resume" % scan), 202, "resume with the camera gone")
        j = d.wait_job(job, "failed")
        err = (j or {}).get("error") or ""
        c.ok("no camera '%s' found by Aravis" % DEVICE in err,
             "the resumed job fails: the named camera is not there: %r" % err)
        d.stop_term()
        d.start("--bench", "aravis", "--camera-timeout", "2")
        c.status(d.post("/api/scans/%d/resume" % scan), 202, "resume on the first camera found")
        j = d.wait_job(job, "failed")
        err = (j or {}).get("error") or ""
        c.ok("taken with the aravis camera %s (serial %s)" % (DEVICE, SERIAL) in err and
             "Aravis-Fake-PLAIN2" in err, "another camera is refused, naming both: %r" % err)
    finally:
        other.close()
    c.eq(db.val("SELECT count(*) FROM frames WHERE scan_id = ?", scan), HOLD_AT,
         "and nothing was stored meanwhile")

    # the camera is back: the scan resumes after its last stored point and completes
    emu.command("start", "ready")
    r = d.post("/api/scans/%d/resume" % scan)
    c.status(r, 202, "resume the scan")
    c.ok(d.wait_job(job, "done") is not None, "the resumed scan completes")
    rows = db.all("SELECT point_index, raw, mean FROM frames WHERE scan_id = ? "
                  "ORDER BY point_index", scan)
    c.eq([row[0] for row in rows], list(range(TOTAL)), "every point exactly once")

    k, m = RASTER["frames"], RASTER["sub_px"]
    bad, means_bad, breaks = [], [], 0
    last = None
    for idx, raw, mean in rows:
        vals = struct.unpack("<%dH" % (k * m * m), raw)
        frames = [vals[f * m * m:(f + 1) * m * m] for f in range(k)]
        for f, fr in enumerate(frames):
            if not ramp_ok(fr, m):
                bad.append((idx, f))
            if last is not None and fr[0] != (last + 256) % 65535:
                breaks += 1  # a frame id not the next one: only where the camera came back
            last = fr[0]
        means = struct.unpack("<%dd" % (m * m), mean)
        want = [sum(fr[p] for fr in frames) / k for p in range(m * m)]
        if any(abs(a - b) > 1e-9 for a, b in zip(means, want)):
            means_bad.append(idx)
    c.eq(bad, [], "every stored frame is the emulator's ramp, pixel for pixel")
    c.eq(breaks, 1, "consecutive frame ids but where the camera came back")
    # the camera's own frame ids and timestamps, stored per frame (schema 10): the ids step by
    # one exactly where the ramp's frame counter does, the timestamps grow frame after frame
    ids, stamps, ramp_steps = [], [], []
    for idx, raw, _ in rows:
        pt = d.get("/api/scans/%d/points/%d" % (scan, idx)).json()
        ids += pt.get("camera_frame_ids") or [None] * k
        stamps += pt.get("timestamps_ns") or [None] * k
        vals = struct.unpack("<%dH" % (k * m * m), raw)
        ramp_steps += [vals[f * m * m] for f in range(k)]
    id_steps = [b - a == 1 for a, b in zip(ids, ids[1:]) if None not in (a, b)]
    ramp_next = [b == (a + 256) % 65535 for a, b in zip(ramp_steps, ramp_steps[1:])]
    c.ok(len(ids) == TOTAL * k and None not in ids and id_steps == ramp_next,
         "camera_frame_ids: +1 from frame to frame exactly where the ramp's counter is (%s)" %
         ids[:8])
    c.eq([v for v, i in zip(ramp_steps, ids) if i is None or v != 256 * i % 65535], [],
         "each frame's id is the F its ramp was drawn with (pixel (0, 0) = 256 F mod 65535)")
    c.ok(None not in stamps and all(b > a for a, b in zip(stamps, stamps[1:])),
         "timestamps_ns: one per frame, increasing (%s)" % stamps[:4])
    c.eq(means_bad, [], "the stored means are the frames' means")

    su = d.get("/api/scans/%d" % scan).json().get("setup") or {}
    cam = su.get("camera") or {}
    c.eq((cam.get("backend"), cam.get("id"), cam.get("vendor"), cam.get("model"),
          cam.get("serial"), cam.get("pixel_format"), cam.get("bits")),
         ("aravis", DEVICE, "Aravis", "Fake", SERIAL, "Mono16", 16),
         "the scan's provenance: the camera that took it")
    c.ok(isinstance(cam.get("firmware"), str) and cam["firmware"].startswith("0."),
         "and its firmware (the emulator's DeviceVersion): %r" % cam.get("firmware"))
    c.eq((su.get("setup"), su.get("centre_um"), su.get("exposure_us")),
         ("none", [(POI[0] + 0.5) * PITCH, (POI[1] + 0.5) * PITCH, 0], 10000),
         "set up by hand: the POI's centre and the exposure as given")
    d.stop_term()


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
