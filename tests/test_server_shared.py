#!/usr/bin/env python3
"""test_server_shared.py IPSD IPS: several ipsd on one PostgreSQL database, on a server of its
own (tests/pg_server.sh in its temporary directory: the test restarts it, which the suite's
shared server must not see while other tests use it).

Four benches (each its own simulated bench, --bench-name bench-a .. bench-d) and a fit worker
without an instrument (--bench none) share a fresh schema. Each bench scans; a bench is killed
(SIGKILL, the `crash` failpoint) in the middle of a scan and started again; another bench is
killed during a fit, and the fit worker takes that fit over once its lease (--lease 2) has run
out; all four scan at once while the fit worker and the benches fit, one of them killed mid-scan
and started again. A calibration stored through one ipsd reaches another's reply cache
(LISTEN/NOTIFY). The database server restarts under a held scan; every ipsd carries on and takes
its bench name's lock again, and a bench whose lock another ipsd of its name took meanwhile
claims nothing until that one stops. psql, reading the database independently, then checks that
nothing was lost and nothing written twice: every scan has each of its points once, every
single-pixel fit job one fit, every pixel one current calibration, and each scan job was claimed
only by its own bench."""
import json
import os
import subprocess
import sys

import ipsd_http
from ipsd_http import Ipsd, wait_for

RASTER = {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}


class PgDb:
    """The shared database read with psql (Debian's postgresql-client), one statement a call."""

    def __init__(self, uri):
        self.uri = uri

    def all(self, sql):
        out = subprocess.run(["psql", "-X", "-At", "-F", "\t", "-v", "ON_ERROR_STOP=1",
                              self.uri, "-c", sql], capture_output=True, text=True, timeout=60)
        if out.returncode != 0:
            raise RuntimeError("psql: %s: %s" % (sql, out.stderr.strip()))
        return [tuple(line.split("\t")) for line in out.stdout.splitlines() if line]

    def val(self, sql):
        rows = self.all(sql)
        return rows[0][0] if rows else None


def fresh_schema(base, schema):
    """The URI of a new, empty schema of the suite's database."""
    subprocess.run(["psql", "-X", "-q", "-v", "ON_ERROR_STOP=1", base, "-c",
                    "SET client_min_messages = warning; DROP SCHEMA IF EXISTS %s CASCADE; "
                    "CREATE SCHEMA %s" % (schema, schema)], check=True, timeout=60)
    return "%s%soptions=-csearch_path%%3D%s" % (base, "&" if "?" in base else "?", schema)


def daemon(exe, tmp, name, uri, daemons):
    d = Ipsd(exe, os.path.join(tmp, name))
    os.makedirs(d.tmp, exist_ok=True)
    d.db = uri
    daemons.append(d)
    return d


PG_SERVER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "pg_server.sh")


def test(c, t, argv, daemons):
    pg_dir = os.path.join(t, "pg")
    start = subprocess.run(["bash", PG_SERVER, "start", pg_dir], capture_output=True, text=True,
                           timeout=600)
    if start.returncode == 77:
        print("no PostgreSQL server binaries: skipped")
        raise SystemExit(77)
    try:
        shared_database(c, t, argv, daemons, pg_dir, start)
    finally:
        for d in daemons:
            d.cleanup()
        subprocess.run(["bash", PG_SERVER, "stop", pg_dir], capture_output=True, timeout=300)


def shared_database(c, t, argv, daemons, pg_dir, start):
    c.eq(start.returncode, 0, "a PostgreSQL server of the test's own: " + start.stderr.strip())
    os.environ["PGPASSFILE"] = os.path.join(pg_dir, "pgpass")
    with open(os.path.join(pg_dir, "uri")) as f:
        base = f.read().strip()
    uri = fresh_schema(base, "t_shared")
    db = PgDb(uri)

    # ---- bad input: one line, exit 2, nothing written ----
    newer = fresh_schema(base, "t_newer")
    subprocess.run(["psql", "-X", "-q", "-v", "ON_ERROR_STOP=1", newer, "-c",
                    "CREATE TABLE ipsd_schema (version integer NOT NULL); "
                    "INSERT INTO ipsd_schema VALUES (999)"], check=True, timeout=60)
    wrong_pass = os.path.join(t, "wrong.pgpass")
    with open(os.environ["PGPASSFILE"]) as f, open(wrong_pass, "w") as g:
        g.write("".join(line.rsplit(":", 1)[0] + ":not-the-password\n" for line in f))
    os.chmod(wrong_pass, 0o600)
    root_crt = os.path.join(pg_dir, "root.crt")
    tls = os.path.exists(root_crt)  # pg_server.sh makes it where openssl is
    bad = [(uri + "&sslmode=verify-full&sslrootcert=" + os.path.join(pg_dir, "other-root.crt"),
            {}, "a server certificate the client does not trust")] if tls else []
    for db_arg, env, what in bad + [
            (base + "?no_such_parameter=1", {}, "a malformed URI"),
            (newer, {}, "a database of a newer schema"),
            (uri, {"PGPASSFILE": wrong_pass}, "a wrong password"),
            ("postgresql://ipsd_writer:secret@127.0.0.1/ipsd", {}, "a password in the URI")]:
        r = subprocess.run([argv[1], "--listen", "127.0.0.1:0", "--db", db_arg],
                           capture_output=True, text=True, timeout=60,
                           env={**os.environ, **env})
        c.eq((r.returncode, len(r.stderr.strip().splitlines())), (2, 1),
             "%s: exit 2 and one line (%s)" % (what, r.stderr.strip()))
        c.ok("secret" not in r.stderr and "not-the-password" not in r.stderr,
             "%s: no password in the message" % what)
    c.eq(PgDb(newer).all("SELECT version FROM ipsd_schema"), [("999",)],
         "the newer database is left as it was")
    c.eq(PgDb(newer).val("SELECT count(*) FROM information_schema.tables WHERE "
                         "table_schema = 't_newer'"), "1", "nothing was created in it")
    c.eq(db.val("SELECT count(*) FROM information_schema.tables WHERE table_schema = "
                "'t_shared'"), "0", "nor in the schema the wrong password was refused on")
    a = daemon(argv[1], t, "a", uri, daemons)
    b = daemon(argv[1], t, "b", uri, daemons)
    # the fit worker over TLS, verifying the server's certificate (when the server has one)
    w = daemon(argv[1], t, "w", uri + ("&sslmode=verify-full&sslrootcert=%s&application_name="
                                       "ipsd_fitter" % root_crt if tls else ""), daemons)
    a.start("--bench-name", "bench-a", "--lease", "2")
    b.start("--bench-name", "bench-b", "--lease", "2")
    w.start("--bench", "none", "--bench-name", "fitter", "--lease", "2")

    if tls:
        c.eq(db.all("SELECT count(*) > 0, bool_and(s.ssl) FROM pg_stat_ssl s JOIN "
                    "pg_stat_activity a USING (pid) WHERE a.application_name = 'ipsd_fitter'"),
             [("t", "t")], "the fit worker's connections are encrypted (pg_stat_ssl, by psql)")
    else:
        print("the test server has no TLS certificate: TLS not checked")

    # ---- three ipsd on one database, each saying what it is ----
    for d, name, bench in ((a, "bench-a", "sim"), (b, "bench-b", "sim"), (w, "fitter", "none")):
        h = d.get("/api/health").json()
        c.eq((h.get("database"), h.get("bench_name"), h.get("bench")), ("postgresql", name, bench),
             "%s: health names the shared database, its name and its bench" % name)
    r = a.post("/api/sensors", {"model": "IMX-S", "serial": "shared-1", "pitch_um": 6})
    c.status(r, 201, "a sensor, created through bench-a")
    sensor = r.json()["id"]
    c.eq(b.get("/api/sensors/%d" % sensor).status, 200, "bench-b sees it")
    r = w.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 10, "row": 10}, "raster": RASTER})
    c.error(r, 409, "", "the fit worker has no instrument: a scan is refused")
    c.ok("no instrument" in r.text, "the refusal says why")

    # ---- each bench scans; bench-a is killed after 4 points of its second scan ----
    def scan(d, col):
        r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": col, "row": 20},
                                  "raster": RASTER, "seed": col})
        c.status(r, 202, "a scan submitted to %s" % d.tmp)
        return r.json()["scan"]["id"], r.json()["job"]["id"]
    s1, j1 = scan(a, 10)
    s2, j2 = scan(b, 30)
    c.ok(a.wait_job(j1, "done") and b.wait_job(j2, "done"), "both benches' scans are done")
    c.eq(db.all("SELECT id, bench, claimed_by FROM jobs WHERE kind = 'scan' ORDER BY id"),
         [(str(j1), "bench-a", "bench-a"), (str(j2), "bench-b", "bench-b")],
         "each scan job belongs to, and was run by, its own bench")
    a.stop_term()
    a.start("--bench-name", "bench-a", "--lease", "2", failpoints="scan.point=crash@4")
    s3, j3 = scan(a, 50)
    c.eq(a.wait_exit(), -9, "bench-a crashed (SIGKILL) after 4 points of its scan")
    c.eq(db.val("SELECT state || ' ' || claimed_by FROM jobs WHERE id = %d" % j3),
         "running bench-a", "its scan job is left running, claimed by bench-a")
    c.eq(b.get("/api/jobs/%d" % j3).json().get("bench"), "bench-a",
         "the API says whose bench it is")
    a.start("--bench-name", "bench-a", "--lease", "2")
    c.ok(a.wait_job(j3, "done"), "bench-a back: its scan resumed and is done")

    # ---- bench-b is killed during a fit: the fit worker takes it over after the lease ----
    fits_so_far = [int(x[0]) for x in db.all("SELECT id FROM jobs WHERE kind = 'fit'")]
    c.ok(all(w.wait_job(j, "done") for j in fits_so_far), "the first three scans' fits are done")
    # only bench-b runs now, so that it is the one that claims the next fit
    c.eq((a.stop_term(), b.stop_term(), w.stop_term()), (0, 0, 0), "all three stop")
    b.start("--bench-name", "bench-b", "--lease", "2", failpoints="fit.step=crash@1")
    s4, j4 = scan(b, 70)
    c.eq(b.wait_exit(), -9, "bench-b crashed during the automatic fit of its scan")
    fit_job = db.val("SELECT id FROM jobs WHERE kind = 'fit' AND scan_id = %d" % s4)
    c.ok(fit_job is not None, "the scan queued its automatic fit")
    c.eq(db.val("SELECT claimed_by FROM jobs WHERE id = %s" % fit_job), "bench-b",
         "bench-b had claimed that fit")
    w.start("--bench", "none", "--bench-name", "fitter", "--lease", "2")
    c.ok(w.wait_job(int(fit_job), "done"), "the fit worker ran the fit after bench-b's lease ran out")
    c.eq(db.val("SELECT claimed_by || ' ' || attempts FROM jobs WHERE id = %s" % fit_job),
         "fitter 2", "claimed a second time, by the fit worker")
    a.start("--bench-name", "bench-a", "--lease", "2")
    b.start("--bench-name", "bench-b", "--lease", "2")
    every_fit = [int(x[0]) for x in db.all("SELECT id FROM jobs WHERE kind = 'fit'")]
    c.ok(all(w.wait_job(j, "done") for j in every_fit), "every fit job is done")

    # ---- four benches scan at once, their fits run anywhere; bench-c is killed mid-scan ----
    cc = daemon(argv[1], t, "c", uri, daemons)
    dd = daemon(argv[1], t, "d", uri, daemons)
    cc.start("--bench-name", "bench-c", "--lease", "2", failpoints="scan.point=crash@5")
    dd.start("--bench-name", "bench-d", "--lease", "2")

    def scan_at(d, col, row):
        r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": col, "row": row},
                                  "raster": RASTER, "seed": col + row})
        c.status(r, 202, "a scan submitted to %s" % d.tmp)
        return r.json()["scan"]["id"], r.json()["job"]["id"]
    at_once = [scan_at(d, col, 40) for d, col in ((a, 10), (b, 30), (cc, 50), (dd, 70))]
    c.eq(cc.wait_exit(), -9, "bench-c crashed (SIGKILL) after 5 points, the others scanning")
    cc.start("--bench-name", "bench-c", "--lease", "2")
    c.ok(all(d.wait_job(j, "done") for d, (_, j) in zip((a, b, cc, dd), at_once)),
         "all four scans are done, bench-c's resumed after its restart")
    c.eq(db.all("SELECT bench, claimed_by FROM jobs WHERE id IN (%s) ORDER BY bench" %
                ", ".join(str(j) for _, j in at_once)),
         [("bench-%s" % x, "bench-%s" % x) for x in "abcd"],
         "each of the four scan jobs ran on its own bench")
    every_fit = [int(x[0]) for x in db.all("SELECT id FROM jobs WHERE kind = 'fit'")]
    c.ok(all(w.wait_job(j, "done") for j in every_fit), "every fit job is done")
    fitters = {x[0] for x in db.all("SELECT DISTINCT claimed_by FROM jobs WHERE kind = 'fit'")}
    c.ok("fitter" in fitters and len(fitters) >= 2,
         "fits were taken by the fit worker and by benches: %s" % sorted(fitters))

    # ---- a calibration stored through one ipsd reaches the others' reply caches ----
    pix = "/api/sensors/%d/pixels/10/20/calibration" % sensor

    def current():
        return int(db.val("SELECT id FROM calibrations WHERE sensor_id = %d AND pixel_col = 10 "
                          "AND pixel_row = 20 AND superseded_by IS NULL" % sensor))
    first = current()
    h0 = a.get("/api/health").json()["calibration_cache"]
    reads = [a.get(pix).json().get("id") for _ in range(3)]
    h1 = a.get("/api/health").json()["calibration_cache"]
    c.eq(reads, [first] * 3, "bench-a reads the pixel's calibration")
    c.ok(h1["hits"] - h0["hits"] >= 2, "from its reply cache after the first read")
    path = os.path.join(t, "pixel.json")
    subprocess.run([argv[2], "simulate", "--scene", "paperlike", "--seed", "7", "-o", path],
                   check=True, stdout=subprocess.DEVNULL)
    with open(path) as f:
        scan_file = json.load(f)
    r = b.post("/api/fits", {"scan": scan_file, "sensor_id": sensor,
                             "pixel": {"col": 10, "row": 20}, "r_max": 2})
    c.status(r, 202, "a new map of that pixel, fitted through bench-b")
    c.ok(r.status == 202 and b.wait_job(r.json()["job"]["id"], "done"), "and stored")
    c.ok(current() != first, "the database holds the new calibration as current")
    c.ok(wait_for(lambda: a.get(pix).json().get("id") == current()),
         "bench-a's next reads serve it (the notification emptied its cache's view)")

    # ---- the database server restarts under a scan held mid-raster: every ipsd carries on ----
    b.stop_term()
    b.start("--bench-name", "bench-b", "--lease", "2", failpoints="scan.point=hold@3")
    s5, j5 = scan(b, 90)
    c.ok(b.wait_held("scan.point", j5), "a scan of bench-b held after its third point")
    restart = subprocess.run(["bash", PG_SERVER, "restart", pg_dir], capture_output=True,
                             text=True, timeout=300)
    c.eq(restart.returncode, 0, "the PostgreSQL server restarted (its connections cut): " +
         restart.stderr.strip())
    b.release("scan.point", j5)
    c.ok(b.wait_job(j5, "done"), "the held scan went on over new connections and is done")
    c.status(a.get("/api/sensors/%d" % sensor), 200, "bench-a reads after the restart")
    r = a.post("/api/sensors", {"model": "IMX-S", "serial": "after-restart", "pitch_um": 6})
    c.status(r, 201, "and writes")
    c.eq(a.get("/api/health").json().get("storage"), "ok", "bench-a's storage is ok")
    r = b.post("/api/fits", {"scan": scan_file, "sensor_id": sensor,
                             "pixel": {"col": 10, "row": 20}, "r_max": 3})
    c.ok(r.status == 202 and b.wait_job(r.json()["job"]["id"], "done"),
         "a third map of the pixel stored through bench-b")
    c.ok(wait_for(lambda: a.get(pix).json().get("id") == current()),
         "bench-a hears of it: its listener is back on the restarted server")

    # ---- the bench names' locks ended with the old connections: each ipsd takes its own again ----
    c.ok(wait_for(lambda: "bench bench-a: its lock on the database taken again" in a.log_text()),
         "bench-a took its bench name's lock again on a new connection")
    c.eq(a.get("/api/health").json().get("bench_lock"), "held", "its health says so")
    second = subprocess.run([argv[1], "--listen", "127.0.0.1:0", "--db", uri, "--bench-name",
                             "bench-a"], capture_output=True, text=True, timeout=60)
    c.ok(second.returncode != 0 and "bench bench-a is in use by another ipsd" in second.stderr,
         "a second bench-a is refused again: %d %s" % (second.returncode, second.stderr.strip()))

    # ---- a second ipsd of bench-c's name takes the lock while bench-c's connection is cut ----
    cc.stop_term()
    cc.start("--bench-name", "bench-c", "--lease", "2", failpoints="bench.lock=hold@2")
    c.ok(cc.wait_held("bench.lock", 0), "bench-c's scan worker held before its second look")
    key = ("locktype = 'advisory' AND objsubid = 2 AND classid = 1768977252 AND "
           "objid = hashtext(current_schema() || ' bench bench-c')::oid")
    c.eq(db.all("SELECT pg_terminate_backend(pid) FROM pg_locks WHERE " + key), [("t",)],
         "the connection holding bench-c's lock cut (pg_terminate_backend)")
    c.ok(wait_for(lambda: db.val("SELECT count(*) FROM pg_locks WHERE " + key) == "0"),
         "its backend has ended and let the lock go")
    c2 = daemon(argv[1], t, "c2", uri, daemons)
    c2.start("--bench-name", "bench-c", "--lease", "2")
    c.eq(c2.get("/api/health").json().get("bench_lock"), "held",
         "another ipsd named bench-c starts and holds the name")
    cc.release("bench.lock", 0)
    c.ok(wait_for(lambda: cc.get("/api/health").json().get("bench_lock") == "lost"),
         "the first bench-c finds its lock taken")
    c.ok("another ipsd of that name took its lock" in cc.log_text(), "and logs it")
    c.eq(c2.stop_term(), 0, "the second bench-c stops")
    c.ok(wait_for(lambda: cc.get("/api/health").json().get("bench_lock") == "held"),
         "the first bench-c holds its name again")
    c.ok("its lock is free again and held by this ipsd" in cc.log_text(), "and logs it")
    c.eq(db.val("SELECT count(*) FROM pg_locks WHERE granted AND " + key), "1",
         "one connection holds it (read by psql)")

    # ---- nothing lost, nothing twice (read by psql), once every fit has ended ----
    every_fit = [int(x[0]) for x in db.all("SELECT id FROM jobs WHERE kind = 'fit'")]
    c.ok(all(a.wait_job(j, "done") for j in every_fit), "every fit job is done")
    c.eq(db.all("SELECT id FROM scans WHERE state <> 'done' OR points_done <> points_total OR "
                "points_total <> (SELECT count(*) FROM frames f WHERE f.scan_id = scans.id)"),
         [], "every scan is done with each of its points stored once")
    c.eq(db.val("SELECT count(*) FROM scans"), "9", "nine scans")
    c.eq(db.all("SELECT j.id FROM jobs j WHERE j.kind = 'fit' AND "
                "(SELECT count(*) FROM fits f WHERE f.job_id = j.id) <> 1"), [],
         "every fit job stored exactly one fit")
    c.eq(db.all("SELECT sensor_id, pixel_col, pixel_row FROM calibrations WHERE superseded_by IS "
                "NULL GROUP BY 1, 2, 3 HAVING count(*) > 1"), [],
         "every pixel has one current calibration")
    c.eq(db.val("SELECT count(*) FROM calibrations WHERE superseded_by IS NULL"), "9",
         "nine pixels calibrated, one per scan")
    c.eq(db.val("SELECT count(*) FROM calibrations WHERE pixel_col = 10 AND pixel_row = 20"), "3",
         "the re-fitted pixel keeps its history: three calibrations, one current")
    c.eq(db.all("SELECT id FROM jobs WHERE kind = 'scan' AND claimed_by <> bench"), [],
         "no scan job was ever run by another bench")
    for d in (a, b, cc, dd, w):
        c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
