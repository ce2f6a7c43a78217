#!/usr/bin/env python3
"""test_server_backup.py IPSD: online backups of a running ipsd's database, read back by
Python's sqlite3 (an independent reader):
  - POST /api/backup while a scan is held after its 40th stored point: 201 with the file, its
    size and "ok"; the copy passes integrity_check, is a self-contained file (journal_mode
    delete), has the live database's schema version, exactly the 40 points stored before it
    began, byte for byte, and the scan's progress counter says 40;
  - a backup taken while the released scan writes freely is a consistent snapshot: its frames
    count equals its scan's points_done (they are committed together), at least 40;
  - the backup needs the write token (401 without), a second ipsd without --backup-dir
    answers 409 backups_off;
  - `ipsd --backup OUT --db LIVE` next to the running ipsd writes a checked copy, and refuses
    an OUT that exists (exit 2); it only reads its source: an older schema is copied as it is,
    a newer one, an empty file and a file that is not SQLite are refused (exit 2, one line), none
    of them written, and a copy that fails for want of space leaves no file behind;
  - restore: ipsd started on a copy of the first backup serves its sensor and scan, and resumes
    the scan that was running in the snapshot to its last point."""
import hashlib
import os
import shutil
import sqlite3
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd

TOKEN = "backup-writer-81d2"


def open_copy(path):
    return sqlite3.connect("file:%s?mode=ro" % path, uri=True, isolation_level=None)


def digest(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def run_backup(exe, db, out, **kw):
    return subprocess.run([exe, "--db", db, "--backup", out], capture_output=True, text=True,
                          timeout=ipsd_http.DEADLINE_S, **kw)


def source_checks(c, t, exe, good):
    """ipsd --backup reads its source and nothing else: an older schema is copied as it is (the
    source's bytes unchanged, the copy at the old version), a newer schema, an empty file and a
    file that is not SQLite are refused with exit 2 and one line, and none of them is written;
    a copy that fails on a full file system leaves no OUT, OUT.part nor OUT.part-journal."""
    version = sqlite3.connect(good).execute("PRAGMA user_version").fetchone()[0]
    cases = {"old.db": version - 1, "new.db": version + 1}
    for name, v in cases.items():
        path = os.path.join(t, name)
        shutil.copyfile(good, path)
        cx = sqlite3.connect(path)
        cx.execute("PRAGMA user_version = %d" % v)
        cx.commit()
        cx.close()
    with open(os.path.join(t, "empty.db"), "wb"):
        pass
    with open(os.path.join(t, "text.db"), "w") as f:
        f.write("not a database\n" * 100)
    before = {n: digest(os.path.join(t, n)) for n in ("old.db", "new.db", "empty.db", "text.db")}
    r = run_backup(exe, os.path.join(t, "old.db"), os.path.join(t, "old-copy.db"))
    c.ok(r.returncode == 0 and "schema %d" % (version - 1) in r.stdout,
         "an older schema is backed up as it is: %d %s %s" % (r.returncode, r.stdout.strip(),
                                                                r.stderr.strip()))
    cp = open_copy(os.path.join(t, "old-copy.db"))
    c.eq(cp.execute("PRAGMA user_version").fetchone()[0], version - 1, "the copy's schema")
    cp.close()
    for name, word in (("new.db", "newer"), ("empty.db", "not an ipsd database"),
                       ("text.db", "not an SQLite database")):
        out = os.path.join(t, name + ".copy")
        r = run_backup(exe, os.path.join(t, name), out)
        lines = r.stderr.strip().split("\n")
        c.ok(r.returncode == 2 and len(lines) == 1 and word in lines[0],
             "%s is refused with exit 2 and one line: %d %r" % (name, r.returncode, r.stderr))
        c.ok(not os.path.exists(out) and not os.path.exists(out + ".part"),
             "%s: no copy made" % name)
    after = {n: digest(os.path.join(t, n)) for n in before}
    c.eq(after, before, "no source file was written (its bytes)")
    c.eq(os.path.getsize(os.path.join(t, "empty.db")), 0, "the empty file stays empty")
    # a real full disk (root only: a tmpfs), at every size from nothing to the copy's: wherever
    # the copy stops, nothing of it is left (the copy's header says WAL, so a copy that could not
    # switch to journal_mode DELETE left OUT.part-wal and OUT.part-shm)
    mnt = os.path.join(t, "tmpfs")
    os.makedirs(mnt)
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4k", "tmpfs",
                                            mnt], stderr=subprocess.DEVNULL).returncode != 0:
        print("full-disk case skipped: cannot mount a tmpfs here")
        return
    subprocess.run(["umount", "-l", mnt])
    size, failed, left = os.path.getsize(good), 0, []
    for kib in range(8, size // 1024 + 48, 8):
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=%dk" % kib, "tmpfs", mnt], check=True)
        try:
            r = run_backup(exe, good, os.path.join(mnt, "full.db"))
            failed += r.returncode == 1
            if r.returncode == 1:
                left += ["%d KiB: %s" % (kib, f) for f in os.listdir(mnt)]
            elif r.returncode != 0 or os.listdir(mnt) != ["full.db"]:
                left.append("%d KiB: exit %d, %r" % (kib, r.returncode, os.listdir(mnt)))
        finally:
            subprocess.run(["umount", "-l", mnt])
    c.ok(failed > 3, "the copy failed for want of space %d times" % failed)
    c.eq(left, [], "a failed copy leaves nothing behind (OUT, OUT.part, -journal, -wal, -shm)")


def test(c, t, argv, daemons):
    exe = argv[1]
    tokfile = os.path.join(t, "token")
    with open(tokfile, "w") as f:
        f.write(TOKEN + "\n")
    auth = {"Authorization": "Bearer " + TOKEN}
    bk = os.path.join(t, "backups")
    os.makedirs(bk)
    live = os.path.join(t, "live")
    os.makedirs(live)
    d = Ipsd(exe, live)
    daemons.append(d)
    d.start("--token", tokfile, "--backup-dir", bk, failpoints="scan.point=hold@40")
    db = Db(d.db)
    r = d.post("/api/sensors", {"model": "IMX-B", "serial": "backup-1"}, headers=auth)
    c.status(r, 201, "sensor")
    sensor = r.json()["id"]
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 30, "row": 30},
                              "raster": {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}},
               headers=auth)
    c.status(r, 202, "scan submitted")
    scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
    total = r.json()["scan"]["raster"]["points_total"]
    c.ok(d.wait_held("scan.point", job), "scan held after its 40th point")

    # ---- a backup of the scan held mid-way ----
    c.error(d.post("/api/backup"), 401, "", "a backup needs the write token")
    # the endpoint has no option: a member is refused, not ignored, and nothing is written
    r = d.post("/api/backup", {"dir": "/tmp"}, headers=auth)
    c.error(r, 422, "dir", "POST /api/backup with an unknown member")
    c.eq(os.listdir(bk), [], "the refused backup wrote nothing")
    r = d.post("/api/backup", headers=auth)
    c.status(r, 201, "POST /api/backup")
    b = r.json()
    path = os.path.join(bk, b["file"])
    c.ok(os.path.isfile(path) and os.path.dirname(os.path.realpath(path)) ==
         os.path.realpath(bk), "the backup is a file in --backup-dir: %r" % b["file"])
    c.eq(b["bytes"], os.path.getsize(path), "its size as answered")
    c.eq(b["integrity"], "ok", "answered integrity")
    c.eq(sorted(os.listdir(bk)), [b["file"]], "no other file left in the directory")
    cp = open_copy(path)
    c.eq(cp.execute("PRAGMA integrity_check").fetchone()[0], "ok", "integrity_check of the copy")
    c.eq(cp.execute("PRAGMA journal_mode").fetchone()[0], "delete", "a self-contained file")
    c.eq(cp.execute("PRAGMA user_version").fetchone()[0], db.val("PRAGMA user_version"),
         "the live database's schema version")
    c.eq(b["schema_version"], db.val("PRAGMA user_version"), "answered schema version")
    c.eq(b["pages"] * cp.execute("PRAGMA page_size").fetchone()[0], b["bytes"],
         "pages x page size = bytes")
    c.eq(cp.execute("SELECT count(*), min(point_index), max(point_index) FROM frames "
                    "WHERE scan_id = ?", (scan,)).fetchone(), (40, 0, 39),
         "the 40 points stored before the backup")
    c.eq(cp.execute("SELECT points_done, state FROM scans WHERE id = ?", (scan,)).fetchone(),
         (40, "running"), "the scan's progress in the copy")
    rows = "SELECT point_index, hex(mean), hex(raw) FROM frames WHERE scan_id = ? ORDER BY 1"
    c.ok(cp.execute(rows, (scan,)).fetchall() == db.all(rows, scan),
         "the copied points equal the live ones, byte for byte")
    c.eq(cp.execute("SELECT model, serial FROM sensors").fetchall(), [("IMX-B", "backup-1")],
         "the sensor in the copy")

    # ---- a backup while the scan writes ----
    d.release("scan.point", job)
    r = d.post("/api/backup", headers=auth)
    c.status(r, 201, "a backup while the scan runs")
    p2 = os.path.join(bk, r.json()["file"])
    c.ok(p2 != path, "a new name for the second backup")
    cp2 = open_copy(p2)
    c.eq(cp2.execute("PRAGMA integrity_check").fetchone()[0], "ok", "second copy's integrity")
    n = cp2.execute("SELECT count(*) FROM frames WHERE scan_id = ?", (scan,)).fetchone()[0]
    done = cp2.execute("SELECT points_done FROM scans WHERE id = ?", (scan,)).fetchone()[0]
    c.ok(40 <= n <= total and n == done,
         "a consistent snapshot: %d frames, points_done %d (40..%d)" % (n, done, total))
    cp2.close()
    c.ok(d.wait_job(job, "done"), "the scan finishes after the backups")
    c.eq(cp.execute("SELECT count(*) FROM frames").fetchone()[0], 40,
         "the first backup did not change")

    # ---- the command-line backup next to the running ipsd ----
    out = os.path.join(t, "cli.db")
    r = subprocess.run([exe, "--db", d.db, "--backup", out], capture_output=True, text=True,
                       timeout=ipsd_http.DEADLINE_S)
    c.ok(r.returncode == 0 and "integrity ok" in r.stdout,
         "ipsd --backup: %d %s %s" % (r.returncode, r.stdout.strip(), r.stderr.strip()))
    cp3 = open_copy(out)
    c.eq(cp3.execute("PRAGMA integrity_check").fetchone()[0], "ok", "the command's copy is sound")
    c.eq(cp3.execute("SELECT count(*) FROM frames WHERE scan_id = ?", (scan,)).fetchone()[0],
         total, "and holds the finished scan")
    cp3.close()
    r = subprocess.run([exe, "--db", d.db, "--backup", out], capture_output=True, text=True,
                       timeout=ipsd_http.DEADLINE_S)
    c.ok(r.returncode == 2 and "exists" in r.stderr, "an existing OUT is refused: %d %s"
         % (r.returncode, r.stderr.strip()))
    r = subprocess.run([exe, "--db", os.path.join(t, "none.db"), "--backup",
                        os.path.join(t, "x.db")], capture_output=True, text=True,
                       timeout=ipsd_http.DEADLINE_S)
    c.ok(r.returncode == 2 and not os.path.exists(os.path.join(t, "none.db")),
         "a missing database is refused, not created")
    c.eq(d.stop_term(), 0, "SIGTERM: exit 0")
    db.close()
    source_checks(c, t, exe, out)

    # ---- no --backup-dir: 409 ----
    other = os.path.join(t, "other")
    os.makedirs(other)
    o = Ipsd(exe, other)
    daemons.append(o)
    o.start()
    r = o.post("/api/backup")
    c.error(r, 409, "", "no --backup-dir")
    c.eq(r.json()["error"]["code"], "backups_off", "its code")
    c.eq(o.stop_term(), 0, "SIGTERM: exit 0")

    # ---- restore: ipsd on a copy of the first backup ----
    rdir = os.path.join(t, "restored")
    os.makedirs(rdir)
    shutil.copyfile(path, os.path.join(rdir, "ipsd.db"))
    cp.close()
    rd = Ipsd(exe, rdir)
    daemons.append(rd)
    rd.start()
    c.eq([(s["model"], s["serial"]) for s in rd.get("/api/sensors").json()["items"]],
         [("IMX-B", "backup-1")], "the restored server's sensors")
    c.ok(rd.wait_job(job, "done"), "the scan running in the snapshot resumes and finishes")
    rdb = Db(rd.db)
    c.eq(rdb.one("SELECT count(*), count(DISTINCT point_index) FROM frames WHERE scan_id = ?",
                 scan), (total, total), "every point exactly once after the restore")
    c.eq(rdb.val("PRAGMA integrity_check"), "ok", "the restored database is sound")
    rdb.close()
    c.eq(rd.stop_term(), 0, "SIGTERM: exit 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
