#!/usr/bin/env python3
"""test_server_storfault.py IPSD: storage faults (a full disk left the scan
and its job running with no error until a restart). Three ways to make the storage refuse writes,
each tested to the same end state:

1. SQLite's own SQLITE_FULL: ipsd's handles are capped with PRAGMA max_page_count
   (IPSD_MAX_DB_PAGES) a few pages above a database padded by a filler table; the scan fails at
   whatever point the cap is reached. Space comes back when the test (Python's sqlite3, another
   writer) deletes the filler: its pages become free pages SQLite reuses.
2. Injected SQLITE_READONLY and SQLITE_IOERR at the storage write gate (IPSD_STORAGE_FAULT_FILE),
   switched on while the scan is held at a known point: every write fails, even the one that
   records the failure, so the failure is kept in memory (GET /api/health) until the file goes.
3. A real full disk: the database on a 16 MiB tmpfs, 14 MiB of it taken by a ballast file (only when this runs as root and may mount;
   skipped otherwise, e.g. in a container without CAP_SYS_ADMIN).
4. PostgreSQL only: ipsd's role loses its write privileges mid-scan (the test's psql, as the
   server's superuser, REVOKEs them while the scan is held at a known point) and gets them back:
   first INSERT on frames alone (the failure is recorded at once), then every write on every
   table (the failure's record too, kept in memory as in 2). The errors are PostgreSQL's
   ("permission denied for table frames"), a "read-only" storage fault.
On PostgreSQL (the suite's _pg run) cases 2 and 4 run; 1 and 3 are SQLite's own.

Every case checks: the job and scan end failed with a message naming the fault and the database
file, a log line says so, no job is left running, the instrument is free (the next scan runs),
the GET endpoints answer 200, /api/health's status says "degraded" with the reasons while the
storage refuses writes ("ok" once it takes them again), and once space is back a resumed scan (POST /api/scans/ID/resume)
completes with its earlier points kept, every point stored exactly once, and PRAGMA
integrity_check ok, all read by Python's sqlite3 module (psql on PostgreSQL). No sleeps: states
are waited for."""
import os
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd, pg_admin, pg_schema_of, wait_for

# 961 points of 12 frames of 9 x 9: about 2.6 kB a point, so the cap below is reached mid-scan
BIG = {"raster": {"area_px": 3, "step_um": 0.6, "sub_px": 9, "frames": 12}}
SMALL = {"raster": {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}}
TOTAL = 961  # both: 31 x 31 points on the default 6 um pitch


PG_URI_FILE = os.environ.get("IPSD_TEST_PG_URI_FILE")


def test(c, t, argv, daemons):
    exe = argv[1]

    def scan_body(sensor, col, kind):
        return dict(kind, sensor_id=sensor, poi={"col": col, "row": 30})

    def check_reads(d, scan, what):
        for path in ("/api/health", "/api/scans", "/api/scans/%d" % scan, "/api/jobs",
                     "/api/sensors", "/api/scans/%d/points/0" % scan):
            c.status(d.get(path), 200, "%s: GET %s" % (what, path))

    def exactly_once(db, scan, n):
        return db.one("SELECT count(*), count(DISTINCT point_index), min(point_index), "
                      "max(point_index) FROM frames WHERE scan_id = ?", scan) == (n, n, 0, n - 1)

    def failed_with(d, db, job, scan, words, what):
        """The job and its scan failed with an error naming the fault (one of words) and the
        database file; nothing left running."""
        j = d.wait_job(job, "failed")
        c.ok(j is not None, "%s: job %d failed" % (what, job))
        # (the API may read it failed from memory before the row is written: wait for the row)
        c.ok(wait_for(lambda: db.val("SELECT state FROM jobs WHERE id = ?", job) == "failed"),
             "%s: job %d's row says failed" % (what, job))
        err = (j or {}).get("error") or ""
        c.ok(any(w in err for w in words) and d.db in err,
             "%s: the job's error names the fault and the database: %r" % (what, err))
        c.eq(db.one("SELECT state, error IS NOT NULL FROM scans WHERE id = ?", scan),
             ("failed", 1), "%s: scan failed with an error" % what)
        c.eq(db.val("SELECT count(*) FROM jobs WHERE state = 'running'"), 0,
             "%s: no job left running" % what)
        c.ok("scan job %d failed: " % job in d.log_text(), "%s: a log line says so" % what)
        return err

    def resume_to_done(d, db, scan, kept, what):
        r = d.post("/api/scans/%d/resume" % scan)
        c.status(r, 202, "%s: resume scan %d" % (what, scan))
        job = r.json()["job"]["id"] if r.status == 202 else 0
        c.ok(d.wait_job(job, "done"), "%s: the resumed scan completes" % what)
        # its automatic fit (queued with the scan's end) ends before the next fault, which must
        # find no job running but its own (it may fail where the disk is still nearly full)
        auto = d.get("/api/jobs?kind=fit&scan=%d" % scan).json()["items"]
        c.ok(auto and wait_for(lambda: d.get("/api/jobs/%d" % auto[0]["id"]).json()["state"]
                               in ("done", "failed")), "%s: its automatic fit ended" % what)
        c.ok(exactly_once(db, scan, TOTAL), "%s: every point exactly once" % what)
        c.eq(db.val("SELECT count(*) FROM frames WHERE scan_id = ? AND point_index < ?", scan,
                    len(kept)), len(kept), "%s: the points stored before the fault kept" % what)
        c.eq([r[0] for r in db.all("SELECT hex(mean) FROM frames WHERE scan_id = ? AND "
                                   "point_index < ? ORDER BY point_index", scan, len(kept))],
             kept, "%s: ... unchanged" % what)
        if not db.postgres:
            c.eq(db.val("PRAGMA integrity_check"), "ok", "%s: integrity_check" % what)

    def means(db, scan):
        return [r[0] for r in db.all("SELECT hex(mean) FROM frames WHERE scan_id = ? "
                                     "ORDER BY point_index", scan)]

    def case_full():
        """1. SQLITE_FULL from SQLite itself (PRAGMA max_page_count)"""
        d = Ipsd(exe, os.path.join(t, "full"))
        os.makedirs(d.tmp)
        daemons.append(d)
        d.start()
        sensor = d.post("/api/sensors", {"model": "IMX-F", "serial": "full-1"}).json()["id"]
        c.eq(d.stop_term(), 0, "first run stops")
        db = Db(d.db)
        db.all("CREATE TABLE filler (b BLOB)")
        db.all("INSERT INTO filler VALUES (zeroblob(4000000))")
        pages = db.val("PRAGMA page_count")
        d.start(env={"IPSD_MAX_DB_PAGES": str(pages + 120)})
        r = d.post("/api/scans", scan_body(sensor, 30, BIG))
        c.status(r, 202, "submit the scan that fills the database")
        s1, j1 = r.json()["scan"]["id"], r.json()["job"]["id"]
        failed_with(d, db, j1, s1, ["full"], "max_page_count")
        n1 = db.val("SELECT count(*) FROM frames WHERE scan_id = ?", s1)
        c.ok(0 < n1 < TOTAL, "failed mid-scan (%d points)" % n1)
        c.eq(db.val("SELECT points_done FROM scans WHERE id = ?", s1), n1, "points_done = rows")
        # recording the failure, an update in place, needed no new page and succeeded, but the
        # database is as full as before: health still says full (it said ok before: any committed
        # write cleared the fault), until a write finds more room than at the fault
        h = d.get("/api/health").json()
        c.ok("full" in (h.get("storage_error") or "") and d.db in h["storage_error"] and
             h.get("storage_faults", 0) > 0, "health tells the fault and the database: %r" % h)
        c.eq(h.get("storage"), "full", "health: still full after a write in place succeeded")
        c.eq(h.get("status"), "degraded", "health's status: degraded while the storage is full")
        c.ok(any("storage full" in x and d.db in x for x in h.get("degraded_reasons", [])),
             "degraded_reasons names the full storage and the database: %r"
             % h.get("degraded_reasons"))
        c.ok(h.get("storage_fault_since_ms"), "and since when")
        check_reads(d, s1, "disk full")
        kept = means(db, s1)
        # the instrument is free: the next scan runs (and fails too: still full)
        r = d.post("/api/scans", scan_body(sensor, 31, BIG))
        if c.status(r, 202, "the next scan is accepted"):
            failed_with(d, db, r.json()["job"]["id"], r.json()["scan"]["id"], ["full"],
                        "next scan, still full")
        c.eq(d.get("/api/health").json().get("storage"), "full", "health: full while it is")
        # space comes back: the filler's pages become free pages
        db.all("DELETE FROM filler")
        r = d.post("/api/scans", scan_body(sensor, 32, SMALL))
        c.status(r, 202, "a new scan after space came back")
        c.ok(d.wait_job(r.json()["job"]["id"], "done"), "the new scan completes")
        h = d.get("/api/health").json()
        c.eq((h.get("storage"), h.get("status"), h.get("degraded_reasons")), ("ok", "ok", []),
             "health: storage ok again, status ok, no reasons")
        db.all("DROP TABLE filler")  # room for the rest of scan 1
        resume_to_done(d, db, s1, kept, "max_page_count")
        c.eq(d.stop_term(), 0, "SIGTERM: exit 0")
        db.close()

    def case_gate():
        """2. read-only and I/O errors at the write gate, even for recording the failure"""
        d = Ipsd(exe, os.path.join(t, "gate"))
        os.makedirs(d.tmp)
        daemons.append(d)
        fault = os.path.join(d.tmp, "storage.fault")
        # hits count over all jobs: the first scan is held at its 50th point, its resume passes hits
        # 51..961, so the second scan's 100th point is hit 1061
        d.start(failpoints="scan.point=hold@50;scan.point=hold@1061",
                env={"IPSD_STORAGE_FAULT_FILE": fault})
        db = Db(d.db)
        sensor = d.post("/api/sensors", {"model": "IMX-G", "serial": "gate-1"}).json()["id"]
        for col, word, words, hit in ((30, "readonly", ["read-only", "readonly"], 50),
                                      (31, "ioerr", ["io-error", "I/O"], 100)):
            what = word
            r = d.post("/api/scans", scan_body(sensor, col, SMALL))
            c.status(r, 202, "%s: submit" % what)
            scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
            c.ok(d.wait_held("scan.point", job), "%s: scan held at point %d" % (what, hit))
            kept = means(db, scan)
            c.eq(len(kept), hit, "%s: %d points stored before the fault" % (what, hit))
            with open(fault, "w") as f:
                f.write(word + "\n")
            d.release("scan.point", job)
            # every write fails, the failure's too: kept in memory, shown by health
            h = wait_for(lambda: (lambda h: h if (h.get("unrecorded_job") or {}).get("id") == job
                                  else None)(d.get("/api/health").json()))
            c.ok(h, "%s: health shows the unrecorded failure of job %d" % (what, job))
            if h:
                c.eq(h["storage"], "read-only" if word == "readonly" else "io-error",
                     "%s: health's storage" % what)
                c.ok(d.db in h["unrecorded_job"]["error"], "%s: its error names the database: %r"
                     % (what, h["unrecorded_job"]["error"]))
                c.eq(h.get("status"), "degraded", "%s: health's status degraded" % what)
                rs = h.get("degraded_reasons", [])
                c.ok(len(rs) == 2 and rs[0].startswith("storage ") and ("job %d " % job) in rs[1],
                     "%s: the reasons name the storage fault and the unrecorded job: %r"
                     % (what, rs))
            check_reads(d, scan, what)
            c.eq(db.val("SELECT state FROM jobs WHERE id = ?", job), "running",
                 "%s: the row cannot be written (still running)" % what)
            j = d.get("/api/jobs/%d" % job).json()
            c.ok(j.get("state") == "failed" and d.db in (j.get("error") or ""),
                 "%s: GET /api/jobs/%d reads it failed from memory: %r" % (what, job, j))
            r = d.post("/api/sensors", {"model": "IMX-G", "serial": "refused-" + word})
            c.ok(r.status in (503, 500) and "error" in r.json(),
                 "%s: a write request gets the JSON error (%d)" % (what, r.status))
            os.remove(fault)  # the storage is back: the worker records the failure
            failed_with(d, db, job, scan, words, what)
            c.eq(wait_for(lambda: d.get("/api/health").json()["unrecorded_job"] is None), True,
                 "%s: nothing unrecorded any more" % what)
            c.ok("cannot record its failure" in d.log_text(), "%s: logged" % what)
            c.eq(db.val("SELECT count(*) FROM frames WHERE scan_id = ?", scan), hit,
                 "%s: no point lost" % what)
            resume_to_done(d, db, scan, kept, what)
        h = d.get("/api/health").json()
        c.eq((h.get("storage"), h.get("status")), ("ok", "ok"),
             "gate: storage and status ok at the end")
        r = d.post("/api/scans/1/resume")
        c.error(r, 409, "", "resuming a done scan is refused")
        c.eq(d.stop_term(), 0, "SIGTERM: exit 0")
        db.close()

    def case_tmpfs():
        """3. a real full disk: the database on a 16 MiB tmpfs (root only)"""
        mnt = os.path.join(t, "tmpfs")
        os.makedirs(mnt)
        if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=16m", "tmpfs",
                                                mnt], stderr=subprocess.DEVNULL).returncode != 0:
            print("real tmpfs case skipped: cannot mount a tmpfs here")
            return
        try:
            d = Ipsd(exe, os.path.join(t, "real"))  # its log and port file off the full disk
            os.makedirs(d.tmp)
            d.db = os.path.join(mnt, "ipsd.db")
            daemons.append(d)
            with open(os.path.join(mnt, "ballast"), "wb") as f:
                # 2 MiB left: the scan fills it; once the ballast goes there is room for the
                # log's data twice (in the log, and in the database file after a checkpoint) and
                # for the log's 1000 pages (4 MB) before SQLite's automatic checkpoint
                f.write(b"\0" * (14 << 20))
            d.start()
            db = Db(d.db)
            sensor = d.post("/api/sensors", {"model": "IMX-T", "serial": "tmpfs-1"}).json()["id"]
            r = d.post("/api/scans", scan_body(sensor, 30, BIG))
            s3, j3 = r.json()["scan"]["id"], r.json()["job"]["id"]
            # the disk fills: the job fails, or its failure does not fit and is kept in memory
            c.ok(wait_for(lambda: db.val("SELECT state FROM jobs WHERE id = ?", j3) == "failed" or
                          (d.get("/api/health").json().get("unrecorded_job") or {}).get("id")
                          == j3),
                 "tmpfs: the scan stops on the full disk")
            c.ok("database or disk is full" in d.log_text(), "tmpfs: logged")
            os.remove(os.path.join(mnt, "ballast"))  # space comes back
            failed_with(d, db, j3, s3, ["full"], "tmpfs")
            check_reads(d, s3, "tmpfs")
            n3 = db.val("SELECT count(*) FROM frames WHERE scan_id = ?", s3)
            c.ok(0 < n3 < TOTAL, "tmpfs: failed mid-scan (%d points)" % n3)
            c.eq(db.val("PRAGMA integrity_check"), "ok", "tmpfs: integrity_check")
            r = d.post("/api/scans", scan_body(sensor, 31, SMALL))
            c.status(r, 202, "tmpfs: a small scan after the ballast went")
            c.ok(d.wait_job(r.json()["job"]["id"], "done"), "tmpfs: it completes")
            c.eq(d.stop_term(), 0, "tmpfs: SIGTERM exit 0")
            db.close()
        finally:
            for x in daemons:
                x.cleanup()
            subprocess.run(["umount", "-l", mnt])

    def case_privilege():
        """4. PostgreSQL: ipsd's role loses its write privileges mid-scan, then gets them back"""
        d = Ipsd(exe, os.path.join(t, "priv"))
        os.makedirs(d.tmp)
        daemons.append(d)
        schema = pg_schema_of(d.db)

        def admin(sql):  # the lab's administrator, in ipsd's schema
            pg_admin(PG_URI_FILE, sql.replace("S.", schema + "."))
        # hits as in case 2: the first scan held at its 50th point, its resume passes hits
        # 51..961 (the scan between fails at its first point: no hit), the third scan's 100th
        # point is hit 1061
        d.start(failpoints="scan.point=hold@50;scan.point=hold@1061")
        db = Db(d.db)
        sensor = d.post("/api/sensors", {"model": "IMX-P", "serial": "priv-1"}).json()["id"]
        words = ["permission denied for table frames"]

        # -- INSERT on frames alone: the point is refused, the failure's record is not --
        what = "revoke insert on frames"
        r = d.post("/api/scans", scan_body(sensor, 30, SMALL))
        c.status(r, 202, "%s: submit" % what)
        scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
        c.ok(d.wait_held("scan.point", job), "%s: scan held at point 50" % what)
        kept = means(db, scan)
        c.eq(len(kept), 50, "%s: 50 points stored before the fault" % what)
        faults = d.get("/api/health").json()["storage_faults"]
        admin("REVOKE INSERT ON S.frames FROM ipsd_writer")
        d.release("scan.point", job)
        err = failed_with(d, db, job, scan, words, what)
        c.ok("read-only" in err, "%s: a read-only storage fault: %r" % (what, err))
        c.ok("scan job %d failed: " % job in d.log_text() and words[0] in d.log_text(),
             "%s: the log line has PostgreSQL's words" % what)
        h = d.get("/api/health").json()
        c.ok(words[0] in (h.get("storage_error") or "") and d.db in h["storage_error"] and
             h.get("storage_faults", 0) > faults,
             "%s: health tells the fault and the database: %r" % (what, h))
        # the failure's record committed, and a write that commits clears the fault
        # (docs/server.md, "Storage faults"): only the points are refused
        c.ok(wait_for(lambda: d.get("/api/health").json()["status"] == "ok"),
             "%s: health's status ok once writes commit" % what)
        check_reads(d, scan, what)
        # the instrument is free: the next scan runs, and fails at its first point
        r = d.post("/api/scans", scan_body(sensor, 31, SMALL))
        if c.status(r, 202, "%s: the next scan is accepted" % what):
            failed_with(d, db, r.json()["job"]["id"], r.json()["scan"]["id"], words,
                        "%s: next scan" % what)
        c.eq(db.val("SELECT count(*) FROM frames WHERE scan_id = ?", scan), 50,
             "%s: no point lost" % what)
        admin("GRANT INSERT ON S.frames TO ipsd_writer")
        resume_to_done(d, db, scan, kept, what)

        # -- every write on every table: the failure's record too, kept in memory --
        what = "revoke every write"
        r = d.post("/api/scans", scan_body(sensor, 32, SMALL))
        c.status(r, 202, "%s: submit" % what)
        scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
        c.ok(d.wait_held("scan.point", job), "%s: scan held at point 100" % what)
        kept = means(db, scan)
        c.eq(len(kept), 100, "%s: 100 points stored before the fault" % what)
        admin("REVOKE INSERT, UPDATE, DELETE ON ALL TABLES IN SCHEMA %s FROM ipsd_writer" % schema)
        d.release("scan.point", job)
        h = wait_for(lambda: (lambda h: h if (h.get("unrecorded_job") or {}).get("id") == job
                              else None)(d.get("/api/health").json()))
        c.ok(h, "%s: health shows the unrecorded failure of job %d" % (what, job))
        if h:
            c.eq((h["storage"], h.get("status")), ("read-only", "degraded"),
                 "%s: health's storage and status" % what)
            ue = h["unrecorded_job"]["error"]
            c.ok(d.db in ue and words[0] in ue, "%s: its error: %r" % (what, ue))
            rs = h.get("degraded_reasons", [])
            c.ok(len(rs) == 2 and rs[0].startswith("storage read-only: ") and
                 ("job %d " % job) in rs[1], "%s: the reasons: %r" % (what, rs))
        check_reads(d, scan, what)
        c.eq(db.val("SELECT state FROM jobs WHERE id = ?", job), "running",
             "%s: the row cannot be written (still running)" % what)
        r = d.post("/api/sensors", {"model": "IMX-P", "serial": "refused"})
        c.error(r, 503, "", "%s: a write request" % what)
        c.eq(r.json().get("error", {}).get("code") if r.status == 503 else None,
             "storage_read_only", "%s: its code" % what)
        c.eq(d.get("/api/health").json()["status"], "degraded",
             "%s: still degraded while writes are refused" % what)
        admin("GRANT INSERT, UPDATE, DELETE ON ALL TABLES IN SCHEMA %s TO ipsd_writer" % schema)
        failed_with(d, db, job, scan, words, what)
        c.eq(wait_for(lambda: d.get("/api/health").json()["unrecorded_job"] is None), True,
             "%s: nothing unrecorded any more" % what)
        c.ok("cannot record its failure" in d.log_text(), "%s: logged" % what)
        c.eq(db.val("SELECT count(*) FROM frames WHERE scan_id = ?", scan), 100,
             "%s: no point lost" % what)
        resume_to_done(d, db, scan, kept, what)
        h = d.get("/api/health").json()
        c.eq((h.get("storage"), h.get("status")), ("ok", "ok"),
             "privileges: storage and status ok at the end")
        c.eq(d.stop_term(), 0, "SIGTERM: exit 0")
        db.close()

    if PG_URI_FILE:  # the gate is every driver's; the page cap and the tmpfs are SQLite's
        case_gate()
        case_privilege()
    else:
        case_full()
        case_gate()
        case_tmpfs()


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
