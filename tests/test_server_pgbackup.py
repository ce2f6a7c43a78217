#!/usr/bin/env python3
"""test_server_pgbackup.py IPSD IPS URI_FILE: a PostgreSQL database backed up and restored the
way docs/operations.md ("A database several benches share", Backups) tells a lab to, with
exactly its commands, against tests/pg_server.sh's server (URI_FILE; PGPASSFILE its password
file):
  - the lab's database made as the page says (a database of its own owned by ipsd_writer, the
    reader's rights), an ipsd on it holding a scan after its 40th stored point (a failpoint);
  - `ipsd --backup` and `POST /api/backup` refuse a PostgreSQL database as documented: exit 2
    and one line naming pg_dump, and 409 backups_off with the JSON error body naming pg_dump
    (with --backup-dir as without), no file written;
  - `pg_dump -Fc` of the database while the scan is held, restored with pg_restore into a new
    database: psql (not ipsd) finds the 40 points, byte for byte the live ones, and the scan's
    progress 40; the reader role reads the copy;
  - an ipsd started on the restored database serves the sensor and the scan, resumes the scan
    that was running in the dump, and finishes it: every point stored exactly once (psql);
  - the live database is untouched by all of it (its 40 points, progress and job as they were),
    and its scan finishes when released.
Without PostgreSQL's server or pg_dump/pg_restore: skipped (77)."""
import os
import shutil
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd, pg_admin

RASTER = {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}
HELD = 40
POINTS = ("SELECT point_index, md5(mean), md5(raw) FROM frames WHERE scan_id = ? "
          "ORDER BY point_index")


def run(argv, **kw):
    return subprocess.run(argv, capture_output=True, text=True, timeout=ipsd_http.DEADLINE_S, **kw)


def test(c, t, argv, daemons):
    exe, uri_file = argv[1], argv[3]
    if not os.path.exists(uri_file):
        print("no PostgreSQL server for the tests (%s): skipped" % uri_file)
        raise SystemExit(77)
    if not (shutil.which("pg_dump") and shutil.which("pg_restore")):
        print("pg_dump or pg_restore missing: skipped")
        raise SystemExit(77)
    with open(uri_file) as f:
        base = f.read().strip()  # postgresql://ipsd_writer@127.0.0.1:PORT/ipsd
    host = base.split("@", 1)[1].rsplit("/", 1)[0]
    live_db, restored_db = "ipsd_live_%d" % os.getpid(), "ipsd_restored_%d" % os.getpid()

    def uri(role, database):
        return "postgresql://%s@%s/%s" % (role, host, database)

    # the password file of this lab: the suite's roles' lines, for the two databases
    with open(os.environ["PGPASSFILE"]) as f:
        lines = [l.rstrip("\n").split(":") for l in f if l.strip()]
    pgpass = os.path.join(t, "pgpass")
    with open(os.open(pgpass, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600), "w") as f:
        for h, port, _, role, pw in lines:
            for name in (live_db, restored_db):
                f.write("%s:%s:%s:%s:%s\n" % (h, port, name, role, pw))
    os.environ["PGPASSFILE"] = pgpass  # for ipsd, psql, pg_dump and pg_restore alike

    # ---- the lab's database, once (docs/operations.md, as the postgres superuser) ----
    pg_admin(uri_file, "CREATE DATABASE %s OWNER ipsd_writer" % live_db)
    try:
        body(c, t, exe, uri_file, uri, live_db, restored_db, daemons)
    finally:
        for d in daemons:
            d.cleanup()
        for name in (live_db, restored_db):
            pg_admin(uri_file, "DROP DATABASE IF EXISTS %s WITH (FORCE)" % name)


def body(c, t, exe, uri_file, uri, live_db, restored_db, daemons):
    pg_admin(uri_file, "ALTER DEFAULT PRIVILEGES FOR ROLE ipsd_writer IN SCHEMA public GRANT "
             "SELECT ON TABLES TO ipsd_reader", live_db)
    pg_admin(uri_file, "GRANT USAGE ON SCHEMA public TO ipsd_reader", live_db)

    live = os.path.join(t, "live")
    os.makedirs(live)
    bk = os.path.join(t, "backups")
    os.makedirs(bk)
    d = Ipsd(exe, live)
    d.db = uri("ipsd_writer", live_db)
    daemons.append(d)
    d.start("--backup-dir", bk, failpoints="scan.point=hold@%d" % HELD)
    db = Db(d.db)
    r = d.post("/api/sensors", {"model": "IMX-PB", "serial": "pgbackup-1"})
    c.status(r, 201, "sensor")
    sensor = r.json()["id"]
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 30, "row": 30},
                              "raster": RASTER})
    c.status(r, 202, "scan submitted")
    scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
    total = r.json()["scan"]["raster"]["points_total"]
    c.ok(d.wait_held("scan.point", job), "scan held after its %dth point" % HELD)

    # ---- ipsd's own backups refuse PostgreSQL, and say so ----
    r = d.post("/api/backup")
    c.error(r, 409, "", "POST /api/backup on PostgreSQL")
    e = r.json().get("error", {}) if r.status == 409 else {}
    c.ok(e.get("code") == "backups_off" and "pg_dump" in e.get("message", ""),
         "its code is backups_off and its message names pg_dump: %r" % e)
    c.eq(os.listdir(bk), [], "nothing written into --backup-dir")
    out = os.path.join(t, "cli.db")
    r = run([exe, "--db", d.db, "--backup", out])
    c.ok(r.returncode == 2 and r.stdout == "" and len(r.stderr.strip().split("\n")) == 1 and
         "pg_dump" in r.stderr, "ipsd --backup on PostgreSQL: exit 2 and one line naming "
         "pg_dump: %d %r %r" % (r.returncode, r.stdout, r.stderr))
    c.ok(not os.path.exists(out), "ipsd --backup wrote no file")

    # ---- pg_dump while the scan is held (as ipsd_writer, which owns what ipsd made) ----
    live_before = db.all(POINTS, scan)
    c.eq(len(live_before), HELD, "the live database holds the %d points" % HELD)
    dump = os.path.join(t, "ipsd.dump")
    r = run(["pg_dump", "-Fc", "-f", dump, uri("ipsd_writer", live_db)])
    c.ok(r.returncode == 0 and os.path.getsize(dump) > 0,
         "pg_dump -Fc: %d %s" % (r.returncode, r.stderr.strip()))

    # ---- restored into a new, empty database ----
    pg_admin(uri_file, "CREATE DATABASE %s OWNER ipsd_writer" % restored_db)
    r = run(["pg_restore", "--exit-on-error", "--single-transaction", "-d",
             uri("ipsd_writer", restored_db), dump])
    c.ok(r.returncode == 0, "pg_restore: %d %s" % (r.returncode, r.stderr.strip()))
    rdb = Db(uri("ipsd_writer", restored_db))
    c.eq(rdb.all(POINTS, scan), live_before, "the copy's points are the live ones, byte for byte")
    c.eq(rdb.one("SELECT points_done, state FROM scans WHERE id = ?", scan), (HELD, "running"),
         "the copy's scan: progress %d, running" % HELD)
    c.eq(rdb.val("SELECT state FROM jobs WHERE id = ?", job), "running", "the copy's job")
    reader = Db(uri("ipsd_reader", restored_db))
    c.eq(reader.val("SELECT count(*) FROM frames WHERE scan_id = ?", scan), HELD,
         "ipsd_reader reads the restored database")

    # ---- an ipsd on the restored database ----
    rdir = os.path.join(t, "restored")
    os.makedirs(rdir)
    rd = Ipsd(exe, rdir)
    rd.db = uri("ipsd_writer", restored_db)
    daemons.append(rd)
    rd.start()
    c.eq([(s["model"], s["serial"]) for s in rd.get("/api/sensors").json()["items"]],
         [("IMX-PB", "pgbackup-1")], "the restored server's sensors")
    r = rd.get("/api/scans/%d" % scan)
    c.status(r, 200, "the restored server serves the scan")
    r = rd.post("/api/backup")  # this one without --backup-dir: the same answer
    c.error(r, 409, "", "POST /api/backup on PostgreSQL without --backup-dir")
    e = r.json().get("error", {}) if r.status == 409 else {}
    c.ok(e.get("code") == "backups_off" and "pg_dump" in e.get("message", ""),
         "without --backup-dir too, backups_off naming pg_dump: %r" % e)
    c.ok(rd.wait_job(job, "done"), "the scan running in the dump resumes and finishes")
    c.eq(rdb.one("SELECT count(*), count(DISTINCT point_index), min(point_index), "
                 "max(point_index) FROM frames WHERE scan_id = ?", scan),
         (total, total, 0, total - 1), "every point stored exactly once after the restore (psql)")
    c.eq(rdb.one("SELECT points_done, state FROM scans WHERE id = ?", scan), (total, "done"),
         "the restored scan is done with every point")
    c.eq(rdb.all(POINTS + " LIMIT %d" % HELD, scan), live_before,
         "the points of the dump are kept as they were")
    c.eq(rd.stop_term(), 0, "restored ipsd: SIGTERM exit 0")

    # ---- the live database untouched ----
    c.eq(db.all(POINTS, scan), live_before, "the live database's points unchanged")
    c.eq(db.one("SELECT points_done, state FROM scans WHERE id = ?", scan), (HELD, "running"),
         "the live scan's progress unchanged")
    c.eq(db.val("SELECT count(*) FROM frames"), HELD, "no other frame in the live database")
    d.release("scan.point", job)
    c.ok(d.wait_job(job, "done"), "the live scan finishes when released")
    c.eq(db.one("SELECT count(*), count(DISTINCT point_index) FROM frames WHERE scan_id = ?",
                scan), (total, total), "the live scan: every point once")
    c.eq(d.stop_term(), 0, "live ipsd: SIGTERM exit 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
