"""ipsd_http.py: what the HTTP tests of ipsd (tests/test_server_*.py) share, standard library only.

- Ipsd: a real daemon on a free loopback port (--listen 127.0.0.1:0, the port read back from
  --port-file) with its database and log in a temporary directory; started, stopped with SIGTERM
  (its exit status) or killed with SIGKILL (a crash); optionally with failpoints armed
  (IPSD_FAILPOINTS, docs/server.md "Test hooks") so a scan or a fit is held at a known point.
- Client: one long-lived HTTP/1.1 client per daemon (http.client, one kept-alive connection).
- EventStream: a reader of GET /api/events in a thread, keeping every line it got.
- Db: the database read by Python's sqlite3 module, an independent reader of what ipsd stored.
- PostgreSQL: with IPSD_TEST_PG_URI_FILE set (tests/server.cmake's *_pg tests: the server of
  tests/pg.cmake), every Ipsd gets a fresh schema of that server's database as its --db, and Db
  reads it with psql instead (the same SQL where SQLite's runs there too); pg_admin() runs SQL as
  that server's superuser (a lab's administrator: privileges, databases).
- wait_for(): polls a condition until a generous deadline: tests wait for states, never for time.
- Checks: counts checks and failures; finish() prints the tally and gives the exit status.
- Recording: with IPSD_API_RECORD_DIR set (tests/server.cmake sets it), every answer a Client or
  an EventStream gets is appended to DIR/<test>.<pid>.jsonl (method, path, status, content type,
  body), which tests/apilint/validate.mjs checks against api/openapi.json (docs/api.md).
"""
import http.client
import json
import os
import shutil
import signal
import socket
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time

try:  # Linux: ipsd gets SIGKILL when the test dies (e.g. killed by ctest's TIMEOUT)
    import ctypes
    _libc = ctypes.CDLL(None, use_errno=True)

    def _die_with_parent():
        _libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
except (OSError, AttributeError):
    _die_with_parent = None

_PG_URI_FILE = os.environ.get("IPSD_TEST_PG_URI_FILE")
_RECORD_DIR = os.environ.get("IPSD_API_RECORD_DIR")
if _RECORD_DIR:  # this test's answers of an earlier run are stale: start its record afresh
    os.makedirs(_RECORD_DIR, exist_ok=True)
    _RECORD_PREFIX = (os.path.basename(sys.argv[0]).rsplit(".", 1)[0] +
                      (".pg." if _PG_URI_FILE else "."))
    for _f in os.listdir(_RECORD_DIR):
        if _f.startswith(_RECORD_PREFIX) and _f.endswith(".jsonl"):
            os.remove(os.path.join(_RECORD_DIR, _f))
_record_lock = threading.Lock()


def _record(method, path, status, content_type, body, events=None, request=None):
    """Appends one answer to this test's record file (no-op unless IPSD_API_RECORD_DIR is set).
    body: bytes (kept as text, lossy for non-UTF-8); events: an event stream's data lines;
    request: the request's body (bytes) when it had one."""
    if not _RECORD_DIR:
        return
    rec = {"method": method, "path": path, "status": status,
           "content_type": (content_type or "").split(";")[0].strip(),
           "body": body.decode("utf-8", "replace") if body is not None else None}
    if events is not None:
        rec["events"] = events
    if request:
        rec["request"] = request.decode("utf-8", "replace")
    name = "%s%d.jsonl" % (_RECORD_PREFIX, os.getpid())
    with _record_lock, open(os.path.join(_RECORD_DIR, name), "a") as f:
        f.write(json.dumps(rec) + "\n")


DEADLINE_S = 60  # how long a wait may take on a busy machine (ASan, other tests) before it fails


def wait_for(cond, timeout=DEADLINE_S, interval=0.005, max_interval=0.05):
    """Calls cond() until it returns a true value (returned) or timeout seconds pass (the last
    false value is returned). The pause between calls grows from interval to max_interval, so a
    long wait does not take much CPU from the daemon it waits for."""
    end = time.monotonic() + timeout
    while True:
        v = cond()
        if v or time.monotonic() > end:
            return v
        time.sleep(interval)
        interval = min(interval * 2, max_interval)


class Checks:
    def __init__(self):
        self.n = 0
        self.fails = 0

    def ok(self, cond, msg):
        """Counts a check; prints msg when cond is false. Returns cond."""
        self.n += 1
        if not cond:
            self.fails += 1
            print("FAIL:", msg, file=sys.stderr, flush=True)
        return cond

    def eq(self, got, want, msg):
        return self.ok(got == want, "%s: got %r, want %r" % (msg, got, want))

    def status(self, r, want, msg):
        return self.ok(r.status == want, "%s: status %d, want %d (body: %s)"
                       % (msg, r.status, want, r.text[:300]))

    def error(self, r, status, field, msg):
        """An error answer: that status and the body {"error": {"code", "message", "field"}}
        naming field ("" for none), with a code and a message."""
        self.status(r, status, msg)
        try:
            e = r.json()["error"]
            got = (e.get("field", ""), bool(e["code"] and e["message"]))
        except (ValueError, KeyError, TypeError):
            got = None
        return self.ok(got == (field, True), "%s: error field, has code and message = %r, want %r "
                       "(body: %s)" % (msg, got, (field, True), r.text[:300]))

    def finish(self):
        print("%d checks, %d failed" % (self.n, self.fails), flush=True)
        return 0 if self.fails == 0 else 1


class Response:
    def __init__(self, status, body, headers):
        self.status = status
        self.body = body
        self.headers = headers
        self._json = None

    @property
    def text(self):
        return self.body.decode("utf-8", "replace")

    def json(self):
        if self._json is None:
            self._json = json.loads(self.body)
        return self._json


class Client:
    """One kept-alive connection to 127.0.0.1:port. A connection the server closed while idle is
    opened again once (the request had not reached the server)."""

    def __init__(self, port, timeout=DEADLINE_S):
        self.port = port
        self.timeout = timeout
        self.conn = None
        self.used = False  # the connection answered a request already

    def close(self):
        if self.conn:
            self.conn.close()
        self.conn = None

    def request(self, method, path, body=None, headers=None, chunked=False):
        """body: a dict or list (sent as JSON), str or bytes. A non-empty body is sent as
        application/json unless headers name a Content-Type (None: send none). chunked:
        Transfer-Encoding: chunked."""
        h = dict(headers or {})
        if isinstance(body, (dict, list)):
            body = json.dumps(body)
        if isinstance(body, str):
            body = body.encode()
        if body and not any(k.lower() == "content-type" for k in h):
            h["Content-Type"] = "application/json"
        h = {k: v for k, v in h.items() if v is not None}
        while True:
            if self.conn is None:
                self.conn = http.client.HTTPConnection("127.0.0.1", self.port,
                                                       timeout=self.timeout)
                self.used = False
            reused = self.used
            try:
                if chunked:
                    self.conn.request(method, path, body=iter([body]), headers=h,
                                      encode_chunked=True)
                else:
                    self.conn.request(method, path, body=body, headers=h)
                r = self.conn.getresponse()
                data = r.read()
            except (http.client.RemoteDisconnected, BrokenPipeError, ConnectionResetError):
                self.close()
                if reused:
                    continue  # a stale kept-alive connection: once more on a new one
                raise
            self.used = True
            if r.will_close:
                self.close()
            _record(method, path, r.status, r.headers.get("Content-Type"), data, request=body)
            return Response(r.status, data, r.headers)


class EventStream:
    """GET path (an event stream) on its own connection, read by a thread into lines. Ready (the
    subscription exists) once the stream's first comment arrived."""

    def __init__(self, port, path="/api/events"):
        self.lines = []
        self.lock = threading.Lock()
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=DEADLINE_S * 3)
        self.sock.sendall(("GET %s HTTP/1.1\r\nHost: 127.0.0.1\r\nAccept: text/event-stream\r\n"
                           "\r\n" % path).encode())
        self.resp = http.client.HTTPResponse(self.sock, method="GET")
        self.resp.begin()
        self.status = self.resp.status
        self.path = path
        self.content_type = self.resp.headers.get("Content-Type")
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()
        self.ready = wait_for(lambda: self.has(": ipsd events"))

    def _read(self):
        try:
            for raw in iter(self.resp.readline, b""):
                with self.lock:
                    self.lines.append(raw.decode().rstrip("\r\n"))
        except (OSError, ValueError, http.client.HTTPException):
            pass  # closed by close() or by ipsd

    def snapshot(self):
        with self.lock:
            return list(self.lines)

    def has(self, line):
        return line in self.snapshot()

    def events(self):
        """The data of every event so far, parsed."""
        return [json.loads(l[6:]) for l in self.snapshot() if l.startswith("data: ")]

    def close(self):
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.thread.join(DEADLINE_S)
        self.resp.close()
        self.sock.close()
        _record("GET", self.path, self.status, self.content_type, None,
                events=[l[6:] for l in self.snapshot() if l.startswith("data: ")])


_pg_schemas = 0


def pg_fresh_database():
    """With IPSD_TEST_PG_URI_FILE: the URI of a new, empty schema of the suite's PostgreSQL
    database (a name of this process's own); None without it."""
    global _pg_schemas
    if not _PG_URI_FILE:
        return None
    if not os.path.exists(_PG_URI_FILE):
        print("no PostgreSQL server for the tests (%s): skipped" % _PG_URI_FILE)
        raise SystemExit(77)
    with open(_PG_URI_FILE) as f:
        base = f.read().strip()
    _pg_schemas += 1
    schema = "t_%d_%d" % (os.getpid(), _pg_schemas)
    subprocess.run(["psql", "-X", "-q", "-v", "ON_ERROR_STOP=1", base, "-c",
                    "SET client_min_messages = warning; DROP SCHEMA IF EXISTS %s CASCADE; "
                    "CREATE SCHEMA %s; CREATE FUNCTION %s.hex(bytea) RETURNS text LANGUAGE sql "
                    "IMMUTABLE AS 'SELECT upper(encode($1, ''hex''))'" % (schema, schema, schema)],
                   check=True, timeout=60)
    return "%s%soptions=-csearch_path%%3D%s" % (base, "&" if "?" in base else "?", schema)


def pg_admin(uri_file, sql, database="ipsd"):
    """Runs sql as the PostgreSQL superuser of tests/pg_server.sh's server whose URI file is
    uri_file (through its unix socket, where local connections are trusted), in database; psql's
    output. What a lab's database administrator does: roles' privileges, databases."""
    d = os.path.dirname(os.path.abspath(uri_file))
    sock = d
    if os.path.exists(os.path.join(d, "rundir")):
        with open(os.path.join(d, "rundir")) as f:
            sock = f.read().strip()
    with open(os.path.join(d, "port")) as f:
        port = f.read().strip()
    out = subprocess.run(["psql", "-X", "-q", "-At", "-v", "ON_ERROR_STOP=1", "-h", sock, "-p",
                          port, "-U", "postgres", "-d", database, "-c", sql],
                         capture_output=True, text=True, timeout=DEADLINE_S)
    if out.returncode != 0:
        raise RuntimeError("psql as postgres: %s: %s" % (sql, out.stderr.strip()))
    return out.stdout


def pg_schema_of(uri):
    """The schema of pg_fresh_database's URI (its search_path option)."""
    return uri.rsplit("search_path%3D", 1)[1].split("&")[0]


class Ipsd:
    """The daemon under test on tmp/ipsd.db, or with IPSD_TEST_PG_URI_FILE on a fresh schema of
    the suite's PostgreSQL database (log: tmp/ipsd.log, appended over restarts)."""

    def __init__(self, exe, tmp):
        self.exe = exe
        self.tmp = tmp
        self.db = pg_fresh_database() or os.path.join(tmp, "ipsd.db")
        self.log = os.path.join(tmp, "ipsd.log")
        self.fp_dir = os.path.join(tmp, "failpoints")
        self.proc = None
        self.client = None
        self.port = None

    def start(self, *args, failpoints=None, env=None):
        """Starts ipsd with args (after --listen, --port-file, --db, --heartbeat 1) and waits for
        its port; failpoints: IPSD_FAILPOINTS for this run (held files in self.fp_dir); env: more
        environment variables for this run (e.g. the storage test hooks)."""
        port_file = os.path.join(self.tmp, "port")
        if os.path.exists(port_file):
            os.remove(port_file)
        extra = env or {}
        env = {k: v for k, v in os.environ.items()
               if not k.startswith(("IPSD_FAILPOINT", "IPSD_STORAGE_FAULT", "IPSD_MAX_DB_PAGES"))}
        env.update(extra)
        if failpoints:
            os.makedirs(self.fp_dir, exist_ok=True)
            env["IPSD_FAILPOINTS"] = failpoints
            env["IPSD_FAILPOINT_DIR"] = self.fp_dir
        with open(self.log, "ab") as log:
            self.proc = subprocess.Popen(
                [self.exe, "--listen", "127.0.0.1:0", "--port-file", port_file, "--db", self.db,
                 "--heartbeat", "1", *args], stdout=log, stderr=subprocess.STDOUT, env=env,
                preexec_fn=_die_with_parent)

        def port():
            try:
                with open(port_file) as f:
                    return f.read().strip() or None
            except FileNotFoundError:
                return "exited" if self.proc.poll() is not None else None
        p = wait_for(port)
        if not p or p == "exited":
            sys.stderr.write("ipsd did not start:\n" + self.log_text())
            raise SystemExit(1)
        self.port = int(p)
        self.client = Client(self.port)
        return self

    def req(self, method, path, body=None, headers=None, chunked=False):
        return self.client.request(method, path, body, headers, chunked)

    def get(self, path, headers=None):
        return self.client.request("GET", path, headers=headers)

    def post(self, path, body=None, headers=None):
        return self.client.request("POST", path, body, headers)

    def stop_term(self):
        """SIGTERM; waits for the exit (a deadline, then SIGKILL); returns the exit status (None
        when it had to be killed)."""
        self.client.close()
        self.proc.send_signal(signal.SIGTERM)
        try:
            rc = self.proc.wait(DEADLINE_S)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            rc = None
        self.proc = None
        return rc

    def stop_kill(self):
        """SIGKILL (a crash) and wait."""
        self.client.close()
        self.proc.kill()
        self.proc.wait()
        self.proc = None

    def wait_exit(self, timeout=DEADLINE_S):
        """Until ipsd exits by itself (a crash failpoint); returns the exit status (-9: SIGKILL),
        or None when it is still running at the deadline (it is then left running)."""
        try:
            rc = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            rc = None
        self.client.close()
        if rc is not None:
            self.proc = None
        return rc

    def cleanup(self):
        if self.proc and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    def log_text(self):
        with open(self.log, errors="replace") as f:
            return f.read()

    # ---- failpoints ----
    def held_path(self, name, job):
        return os.path.join(self.fp_dir, "%s.%d.held" % (name, job))

    def wait_held(self, name, job, timeout=DEADLINE_S):
        """Until the worker holds job at failpoint name (its held file exists)."""
        return wait_for(lambda: os.path.exists(self.held_path(name, job)), timeout)

    def release(self, name, job):
        os.remove(self.held_path(name, job))

    def release_when_held(self, name, job, timeout=DEADLINE_S):
        """Until the worker holds job at name, then releases it (a hold armed with a crash
        crashes there); whether it was held."""
        held = self.wait_held(name, job, timeout)
        if held:
            self.release(name, job)
        return held

    def wait_hold_ended(self, name, job, timeout=DEADLINE_S):
        """Until the worker left the hold (it removes the held file when a cancel or the
        shutdown ends it, before it goes on)."""
        return wait_for(lambda: not os.path.exists(self.held_path(name, job)), timeout)

    # ---- jobs ----
    def job_state(self, job):
        r = self.get("/api/jobs/%d" % job)
        return r.json().get("state") if r.status == 200 else None

    def wait_job(self, job, want, timeout=DEADLINE_S):
        """Polls GET /api/jobs/ID until its state is want; the last answer's JSON, or None (after
        saying what the state was)."""
        last = {}

        def reached():
            nonlocal last
            r = self.get("/api/jobs/%d" % job)
            last = r.json() if r.status == 200 else {"state": "HTTP %d" % r.status}
            return last.get("state") == want
        if wait_for(reached, timeout):
            return last
        print("job %d is %r, not %r after %ds" % (job, last.get("state"), want, timeout),
              file=sys.stderr)
        return None


class _PsqlConn:
    """Db's reader of a PostgreSQL database: psql, one statement a call, its ? parameters written
    in as SQL literals, each value read back as the type SQLite's module would give (integer,
    real, text, bytes for bytea, None for NULL)."""

    NULL = "\x1e"

    def __init__(self, uri):
        self.uri = uri

    @staticmethod
    def _literal(v):
        if v is None:
            return "NULL"
        if isinstance(v, bool):
            return "1" if v else "0"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, bytes):
            return "'\\x%s'::bytea" % v.hex()
        return "'%s'" % str(v).replace("'", "''")

    @classmethod
    def _value(cls, text):
        if text == cls.NULL:
            return None
        if text.startswith("\\x"):
            return bytes.fromhex(text[2:])
        if text in ("t", "f"):  # a boolean, which SQLite gives as 1 or 0
            return int(text == "t")
        for kind in (int, float):
            try:
                return kind(text)
            except ValueError:
                pass
        return text

    def execute(self, query, args=()):
        parts = query.split("?")
        if len(parts) - 1 != len(args):
            raise ValueError("%d parameters for %d placeholders: %s" % (len(args),
                                                                       len(parts) - 1, query))
        sql = parts[0] + "".join(self._literal(a) + p for a, p in zip(args, parts[1:]))
        out = subprocess.run(["psql", "-X", "-At", "-F", "\x1f", "-P", "null=" + self.NULL,
                              "-v", "ON_ERROR_STOP=1", self.uri, "-c", sql],
                             capture_output=True, text=True, timeout=DEADLINE_S)
        if out.returncode != 0:
            raise RuntimeError("psql: %s: %s" % (sql, out.stderr.strip()))
        rows = [tuple(self._value(v) for v in line.split("\x1f"))
                for line in out.stdout.split("\n") if line]
        return _Rows(rows)

    def close(self):
        pass


class _Rows:
    def __init__(self, rows):
        self.rows = rows

    def fetchall(self):
        return self.rows

    def fetchone(self):
        return self.rows[0] if self.rows else None


class Db:
    """The test database read (and, for crafted rows, written) by Python's sqlite3 module: each
    statement in its own transaction, so it sees what ipsd committed. A postgresql:// URI is read
    with psql instead (_PsqlConn)."""

    def __init__(self, path):
        self.postgres = path.startswith(("postgresql://", "postgres://"))
        if self.postgres:
            self.conn = _PsqlConn(path)
        else:
            self.conn = sqlite3.connect(path, timeout=DEADLINE_S, isolation_level=None)

    def all(self, query, *args):
        return self.conn.execute(query, args).fetchall()

    def one(self, query, *args):
        """The first row (a tuple), or None."""
        return self.conn.execute(query, args).fetchone()

    def val(self, query, *args):
        """The first column of the first row."""
        row = self.one(query, *args)
        return row[0] if row else None

    def close(self):
        self.conn.close()


def main(test, argv):
    """Runs test(checks, tmp, argv, daemons) in a temporary directory, removed afterwards, and
    returns the exit status. test appends its Ipsd instances to daemons: any left running at the
    end (a failed test) is killed."""
    checks = Checks()
    tmp = tempfile.mkdtemp(prefix="ipsd-http-", dir=os.environ.get("TMPDIR"))
    daemons = []
    try:
        test(checks, tmp, argv, daemons)
    finally:
        for d in daemons:
            d.cleanup()
        if checks.fails:  # what ipsd said is the evidence of a failure: shown before it is removed
            for log in sorted({d.log for d in daemons}):
                try:
                    with open(log, errors="replace") as f:
                        tail = f.read()[-4000:]
                except OSError:
                    continue
                print("---- ipsd's log (%s), last %d characters:\n%s" % (log, len(tail), tail),
                      file=sys.stderr, flush=True)
        shutil.rmtree(tmp, ignore_errors=True)
    return checks.finish()
