#!/usr/bin/env python3
"""pg_sql_check.py: storage/'s SQL against a real PostgreSQL server (tests/pg.cmake).

    tests/pg_sql_check.py [-v] URI | --uri-file FILE     (the password: PGPASSFILE)

Reads every SQL text of storage/ as the compiler sees it (a tiny C program built from
storage_sql.c and storage_sql_pg.c prints them), checks that PostgreSQL's texts number their
parameters as SQLite's do (?N, which the driver writes $N and counts: sqldb.h) and leave the two
BEGINs to the driver (sqldb_pg.c runs them its own way), then, in schemas of its own that it
drops at the end:
  - applies PostgreSQL's migrations as storage.c does (each a multi-statement string, one
    transaction) on a new schema alone, and after stg_pg_bootstrap (which must leave version 0)
    with the NULL ones stepping the version; STG_USER_VERSION's text must read stg_n_migrations;
  - checks that a bad JSON document breaks its column's CHECK (SQLSTATE 23514, the constraint
    SQLite names), and that a good one passes, as SQLite's json_valid says of each;
  - runs each transaction statement as the driver does and PREPAREs every other statement in
    PostgreSQL's text (stg_sql_pg, else stg_sql; ?N written $N): each must prepare, with as many
    parameters as SQLite's text numbers and no boolean or unknown result column;
  - runs the same script of statements on SQLite (Python's sqlite3, a database made by
    stg_migrations) and on PostgreSQL, and compares what each returns and changes, value by
    value: a column SQLite returns as an integer must read as one from PostgreSQL's text.
Exits 1 naming what failed; 77 when PostgreSQL is not installed and the URI file is missing (the
server fixture skipped)."""
import argparse
import os
import re
import shutil
import sqlite3
import struct
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
STORAGE = os.path.join(ROOT, "storage")
FAILURES = []


def fail(msg):
    FAILURES.append(msg)
    print("FAIL: " + msg, file=sys.stderr)


# ---- the SQL texts, as compiled -----------------------------------------------------------

DUMPER = r"""
#include <stdio.h>
#include "storage_sql.c"
#include "storage_sql_pg.c"

_Static_assert(sizeof stg_pg_migrations / sizeof stg_pg_migrations[0] ==
                   sizeof stg_migrations / sizeof stg_migrations[0],
               "stg_pg_migrations must have as many entries as stg_migrations");

/* '+' text or '-' (NULL), each ended by a NUL */
static void put(const char *s)
{
    if (s) {
        putchar('+');
        fputs(s, stdout);
    } else {
        putchar('-');
    }
    putchar('\0');
}

int main(void)
{
    put(stg_pg_bootstrap);
    printf("%d", (int)STG_N);
    putchar('\0');
    for (int i = 0; i < STG_N; i++) {
        put(stg_sql[i]);
        put(stg_sql_pg[i]);
    }
    printf("%d", stg_n_migrations);
    putchar('\0');
    for (int i = 0; i < stg_n_migrations; i++) {
        put(stg_migrations[i]);
        put(stg_pg_migrations[i]);
    }
    return 0;
}
"""


def load_sql():
    """{'ids': [names], 'sql': [sqlite], 'pg': [pg or None], 'mig': [...], 'pg_mig': [...]}"""
    with open(os.path.join(STORAGE, "storage_int.h"), encoding="utf-8") as f:
        header = f.read()
    m = re.search(r"enum\s+stg_id\s*\{(.*?)\};", header, re.S)
    if not m:
        sys.exit("pg_sql_check: no enum stg_id in storage/storage_int.h")
    body = re.sub(r"/\*.*?\*/", "", m.group(1), flags=re.S)
    ids = [w.strip() for w in body.split(",") if w.strip()]
    if ids[-1] != "STG_N":
        sys.exit("pg_sql_check: enum stg_id does not end with STG_N")
    ids = ids[:-1]
    cc = os.environ.get("CC") or "cc"
    with tempfile.TemporaryDirectory(prefix="pg_sql_check.") as tmp:
        src, exe = os.path.join(tmp, "dump.c"), os.path.join(tmp, "dump")
        with open(src, "w", encoding="utf-8") as f:
            f.write(DUMPER)
        build = subprocess.run([cc, "-std=c11", "-Wall", "-Wextra", "-Werror", "-I", ROOT,
                                "-I", STORAGE, src, "-o", exe],
                               capture_output=True, text=True)
        if build.returncode != 0:
            sys.exit("pg_sql_check: the SQL texts do not compile:\n" + build.stderr)
        out = subprocess.run([exe], capture_output=True, check=True).stdout
    parts = out.decode("utf-8").split("\0")
    pos = 0

    def take():
        nonlocal pos
        pos += 1
        return parts[pos - 1]

    def text():
        t = take()
        return t[1:] if t.startswith("+") else None

    bootstrap = text()
    n = int(take())
    if n != len(ids):
        sys.exit("pg_sql_check: STG_N is %d but enum stg_id names %d" % (n, len(ids)))
    sql, pg = [], []
    for _ in range(n):
        sql.append(text())
        pg.append(text())
    nm = int(take())
    mig, pg_mig = [], []
    for _ in range(nm):
        mig.append(text())
        pg_mig.append(text())
    return {"ids": ids, "sql": sql, "pg": pg, "mig": mig, "pg_mig": pg_mig,
            "bootstrap": bootstrap}


def outside_literals(sql):
    """(start, end) spans of sql outside its '...' literals and "..." names"""
    spans, i, start, n = [], 0, 0, len(sql)
    while i < n:
        c = sql[i]
        if c in "'\"":
            spans.append((start, i))
            j = i + 1
            while j < n:
                if sql[j] == c:
                    if j + 1 < n and sql[j + 1] == c:
                        j += 2
                        continue
                    break
                j += 1
            i = start = j + 1
        else:
            i += 1
    spans.append((start, n))
    return spans


def dollar_params(sql):
    """?N written $N outside literals, as the driver does"""
    out, last = [], 0
    for a, b in outside_literals(sql):
        out.append(sql[last:a])
        out.append(re.sub(r"\?(\d+)", r"$\1", sql[a:b]))
        last = b
    out.append(sql[last:])
    return "".join(out)


def params_of(sql, mark):
    found = set()
    for a, b in outside_literals(sql):
        found.update(int(x) for x in re.findall(re.escape(mark) + r"(\d+)", sql[a:b]))
    return found


def pg_text(s, i):
    """what the driver prepares: PostgreSQL's text, else SQLite's, ?N written $N"""
    return dollar_params(s["pg"][i] if s["pg"][i] is not None else s["sql"][i])


def is_transaction(sql):
    return re.match(r"\s*(BEGIN|COMMIT|ROLLBACK|END|START)\b", sql, re.I) is not None


# The driver knows SQLite's two BEGINs by their text and runs them its own way (sqldb_pg.c): a
# write takes the writers' advisory lock after BEGIN, a read is one REPEATABLE READ snapshot.
WRITE_LOCK = "SELECT pg_advisory_xact_lock(1768977252, hashtext(current_schema()))"


def driver_runs(sql):
    """the statements the driver runs for a transaction statement's text"""
    if re.match(r"\s*BEGIN\s+IMMEDIATE\b", sql, re.I):
        return ["BEGIN ISOLATION LEVEL READ COMMITTED", WRITE_LOCK]
    if re.match(r"\s*BEGIN\s*$", sql, re.I):
        return ["BEGIN ISOLATION LEVEL REPEATABLE READ"]
    return [sql]


def static_checks(s):
    for i, name in enumerate(s["ids"]):
        if s["sql"][i] is None:
            fail("%s: no SQLite text" % name)
            continue
        want = params_of(s["sql"][i], "?")
        if s["pg"][i] is not None:
            if params_of(s["pg"][i], "$"):
                fail("%s: PostgreSQL's text has $N placeholders: the driver counts ?N only "
                     "(sqldb.h)" % name)
            got = params_of(s["pg"][i], "?")
            if got != want:
                fail("%s: PostgreSQL's text has parameters %s, SQLite's %s"
                     % (name, sorted(got), sorted(want)))
        if want and want != set(range(1, max(want) + 1)):
            fail("%s: parameters %s are not 1..N" % (name, sorted(want)))
    pm = s["pg_mig"]
    if not pm or pm[-1] is None:
        fail("stg_pg_migrations: the last migration is NULL")
    # the texts the driver must know as a write and a read transaction
    ids = s["ids"]
    for name, want in (("STG_BEGIN_WRITE", "BEGIN IMMEDIATE"), ("STG_BEGIN_READ", "BEGIN")):
        i = ids.index(name)
        text = s["pg"][i] if s["pg"][i] is not None else s["sql"][i]
        if text.strip().upper() != want:
            fail("%s: the driver runs %r its own way, not %r (sqldb_pg.c)" % (name, want, text))


# ---- PostgreSQL through psql --------------------------------------------------------------

def pg_bindirs():
    """where PostgreSQL's binaries may be, as tests/pg_server.sh looks (IPSD_PG_BINDIR: only
    there)"""
    if "IPSD_PG_BINDIR" in os.environ:
        return [os.environ["IPSD_PG_BINDIR"]]
    dirs = ["/usr/lib/postgresql/15/bin"]
    try:
        dirs.append(subprocess.run(["pg_config", "--bindir"], capture_output=True,
                                   text=True).stdout.strip())
    except OSError:
        pass
    initdb = shutil.which("initdb")
    if initdb:
        dirs.append(os.path.dirname(initdb))
    return [d for d in dirs if d]


def pg_installed():
    return any(os.access(os.path.join(d, "initdb"), os.X_OK) for d in pg_bindirs())


def find_psql():
    for d in pg_bindirs():
        if os.access(os.path.join(d, "psql"), os.X_OK):
            return os.path.join(d, "psql")
    return shutil.which("psql")


class Pg:
    def __init__(self, psql, uri, schema):
        self.psql, self.uri, self.schema = psql, uri, schema

    def env(self, schema):
        env = dict(os.environ)
        # only the check's own schema: nothing it makes lands anywhere else
        if schema:
            env["PGOPTIONS"] = "-c search_path=%s -c client_min_messages=warning" % schema
        else:
            env["PGOPTIONS"] = "-c client_min_messages=warning"
        return env

    def command(self, sql, schema=True):
        """one simple-query string (PQexec's way: several statements, one transaction)"""
        return subprocess.run([self.psql, "-X", "-w", "-q", "-At", "-d", self.uri, "-c", sql],
                              capture_output=True, text=True,
                              env=self.env(self.schema if schema else None))

    def script(self, text, schema=None):
        """a psql script from stdin, errors not stopping it: (stdout, stderr)"""
        r = subprocess.run([self.psql, "-X", "-w", "-At", "-F", "\x1f", "-v", "ON_ERROR_STOP=0",
                            "-d", self.uri, "-f", "-"],
                           input=text, capture_output=True, text=True,
                           env=self.env(schema or self.schema))
        return r.stdout, r.stderr


class Script:
    """a psql script, one SQL statement a line, whose lines remember what they are for"""

    def __init__(self):
        self.lines, self.tag = [], {}

    def add(self, text, tag=None):
        self.lines.append(" ".join(text.split("\n")))
        if tag is not None:
            self.tag[len(self.lines)] = tag

    def mark(self, k):
        self.add("\\echo @@%d" % k)

    def text(self):
        return "\n".join(self.lines) + "\n"

    def errors(self, stderr):
        """{tag: error text} of psql's 'psql:<stdin>:LINE: ERROR: ...' lines; untagged lines
        under their line number"""
        errs = {}
        for m in re.finditer(r"^psql:<stdin>:(\d+): (?:ERROR|FATAL):\s*(.*)$", stderr, re.M):
            line = int(m.group(1))
            errs.setdefault(self.tag.get(line, "line %d" % line), m.group(2))
        return errs


def sections(stdout):
    """{k: [lines]} of the output after each \\echo @@k"""
    out, cur = {}, None
    for line in stdout.split("\n"):
        m = re.fullmatch(r"@@(\d+)", line)
        if m:
            cur = int(m.group(1))
            out[cur] = []
        elif cur is not None:
            out[cur].append(line)
    if cur is not None and out[cur] and out[cur][-1] == "":
        out[cur].pop()  # the output's last newline
    return out


def literal(v):
    """a parameter as the driver sends it (text; a BLOB as bytea), written as a SQL literal
    of unknown type, which EXECUTE gives the statement's parameter type"""
    if v is None:
        return "NULL"
    if isinstance(v, bytes):
        return "'\\x%s'" % v.hex()
    if isinstance(v, float):
        return "'%.17g'" % v
    if isinstance(v, int):
        return "'%d'" % v
    return "'%s'" % v.replace("'", "''")


def execute(name, params):
    if not params:
        return "EXECUTE %s" % name.lower()
    return "EXECUTE %s(%s)" % (name.lower(), ", ".join(literal(p) for p in params))


def nparams(s, i):
    want = params_of(s["sql"][i], "?")
    return max(want) if want else 0


def new_schema(pg, schema, s):
    """schema made and migrated as on a new database; None or an error"""
    r = pg.command("CREATE SCHEMA %s" % schema, schema=False)
    if r.returncode:
        return r.stderr.strip()
    sub = Pg(pg.psql, pg.uri, schema)
    for to, sql in enumerate(s["pg_mig"], 1):
        if sql is not None:
            r = sub.command(sql)
            if r.returncode:
                return "migration %d: %s" % (to, r.stderr.strip())
    return None


def check_migrations(pg, s, base):
    """the migrations alone on a new schema (base_a), and as storage.c runs them on a new
    database (base_b): stg_pg_bootstrap first, the NULL migrations stepping the version; each
    must leave one row, the last version. False when a migration failed."""
    n = len(s["pg_mig"])
    version_sql = pg_text(s, s["ids"].index("STG_USER_VERSION"))
    err = new_schema(pg, base + "_a", s)
    if err:
        fail("PostgreSQL's migrations on a new schema: " + err)
        return False
    r = pg.command("CREATE SCHEMA %s_b" % base, schema=False)
    if r.returncode:
        fail("cannot create schema %s_b: %s" % (base, r.stderr.strip()))
        return False
    sub = Pg(pg.psql, pg.uri, base + "_b")
    # as storage.c opens a new database: the bootstrap (at every open: twice), then each
    # migration, a NULL one only stepping the version
    steps = [s["bootstrap"], s["bootstrap"]]
    steps += [sql if sql is not None else "UPDATE ipsd_schema SET version = %d" % to
              for to, sql in enumerate(s["pg_mig"], 1)]
    steps.append(s["bootstrap"])
    for k, sql in enumerate(steps):
        r = sub.command(sql)
        if r.returncode:
            fail("stg_pg_bootstrap and PostgreSQL's migrations: %s" % r.stderr.strip())
            return False
        if k < 2:  # a new database's version, as storage.c reads it next
            r = sub.command(version_sql)
            if r.returncode or r.stdout.split() != ["0"]:
                fail("after stg_pg_bootstrap, %s gave %r %s, not the single row 0"
                     % (version_sql, r.stdout, r.stderr.strip()))
                return False
    for schema in (base + "_a", base + "_b"):
        sub = Pg(pg.psql, pg.uri, schema)
        r = sub.command(version_sql)
        if r.returncode or r.stdout.split() != [str(n)]:
            fail("schema %s: %s gave %r %s, not the single row %d"
                 % (schema, version_sql, r.stdout, r.stderr.strip(), n))
        if sub.command("INSERT INTO ipsd_schema VALUES (%d)" % n).returncode == 0:
            fail("schema %s: ipsd_schema took a second row" % schema)
    return True


def check_json(pg, verbose):
    """bad JSON: a CHECK violation (SQLSTATE 23514) of SQLite's constraint; good JSON passes;
    SQLite's json_valid says the same of each document"""
    sc = Script()
    sc.add("\\set VERBOSITY verbose")
    sc.add("INSERT INTO sensors (model, serial, n_cols, n_rows, pitch_um, gain_e_per_dn, "
           "read_noise_e, bias_dn, full_scale_dn, created_ms) "
           "VALUES ('m', 's', 10, 10, 5, 1, 1, 0, 4095, 0) RETURNING id;", "setup")
    sc.add("INSERT INTO scans (sensor_id, poi_col, poi_row, wavelength_um, na, spot_radius_um, "
           "area_px, step_um, sub_px, frames, exposure_us, points_total, created_ms) "
           "SELECT max(id), 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0 FROM sensors;", "setup")
    job = "INSERT INTO jobs (kind, params, created_ms) VALUES ('fit', %s, 0)"
    cases = [  # (statement with %s for the document, document, constraint it breaks or None)
        (job, "{bad", "params_json"),
        (job, "", "params_json"),
        (job, "{\"a\": 1} x", "params_json"),
        (job, "[" * 100000 + "]" * 100000, "params_json"),  # past the parser's stack
        (job, "[01]", "params_json"),
        (job, '["\t"]', "params_json"),  # a control character in a string
        (job, '{"a": 1,}', "params_json"),
        (job, "TRUE", "params_json"),
        (job, '{"a": 1, "a": [1e999, -0]}', None),
        (job, '{"pixels": "all", "r": [1, 2.5e3, null, true, "\\u00e9"]}', None),
        (job, ' "text" ', None),
        ("INSERT INTO fits (dcol, drow, noise_model, result, created_ms) "
         "VALUES (0, 0, 'paper', %s, 0)", "[1,", "result_json"),
        ("INSERT INTO fits (dcol, drow, noise_model, result, created_ms) "
         "VALUES (0, 0, 'paper', %s, 0)", "{}", None),
        ("INSERT INTO ptc (sensor_id, gain_e_per_dn, read_noise_e, result, created_ms) "
         "SELECT max(id), 1, 1, %s, 0 FROM sensors", "NaN", "result_json"),
        ("UPDATE scans SET setup = %s", "{'a': 1}", "setup_json"),
        ("UPDATE scans SET setup = %s", None, None),
    ]
    for k, (sql, doc, _) in enumerate(cases):
        sc.add(sql % literal(doc) + ";", k)
    lite = sqlite3.connect(":memory:")
    for sql, doc, constraint in cases:
        if doc is not None and lite.execute("SELECT json_valid(?)", (doc,)).fetchone()[0] != \
                (constraint is None):
            fail("the case %r is not what SQLite's json_valid says" % doc[:24])
    lite.close()
    out, err = pg.script(sc.text())
    errs = sc.errors(err)
    if "setup" in errs:
        fail("JSON check: its rows: %s" % errs["setup"])
        return
    for k, (sql, doc, constraint) in enumerate(cases):
        got = errs.get(k)
        what = "%s ... %s" % (" ".join(sql.split()[:3]), "NULL" if doc is None else repr(doc[:24]))
        if constraint is None:
            if got:
                fail("%s: refused: %s" % (what, got))
        elif not got:
            fail("%s: accepted" % what)
        elif not got.startswith("23514:") or ('"%s"' % constraint) not in got:
            fail("%s: not a violation (23514) of %s: %s" % (what, constraint, got))
        elif verbose:
            print("ok: %s: %s" % (what, got[:110]))


def check_prepare(pg, s, verbose):
    """every statement runs (transactions) or prepares, with SQLite's parameter count and no
    boolean or unknown result column"""
    ids = s["ids"]
    sc = Script()
    tx = [i for i in range(len(ids)) if is_transaction(s["sql"][i])]
    begins = [i for i in tx if re.match(r"\s*(BEGIN|START)", pg_text(s, i), re.I)]
    ends = [i for i in tx if i not in begins]
    order = []
    for k, b in enumerate(begins):  # each BEGIN ended by one of the ends, in turn
        order += [b, ends[k % len(ends)]] if ends else [b]
    order += ends[len(begins):]
    for i in order:
        for sql in driver_runs(pg_text(s, i)):
            sc.add(sql + ";", ids[i])
    stmts = [i for i in range(len(ids)) if i not in tx]
    for i in stmts:
        sc.add("PREPARE %s AS %s;" % (ids[i].lower(), pg_text(s, i)), ids[i])
    sc.add("\\echo @@0")
    sc.add("SELECT name, parameter_types::text FROM pg_prepared_statements;")
    for i in stmts:
        sc.mark(i + 1)
        sc.add(execute(ids[i], [None] * nparams(s, i)) + " \\gdesc", ids[i])
    out, err = pg.script(sc.text())
    errs = sc.errors(err)
    for tag, msg in errs.items():
        fail("%s: %s" % (tag, msg))
        if tag in ids:
            print("    " + pg_text(s, ids.index(tag)), file=sys.stderr)
    sec = sections(out)
    ptypes = dict(line.split("\x1f", 1) for line in sec.get(0, []) if "\x1f" in line)
    result_types = {}
    for i in stmts:
        name = ids[i]
        if name in errs:
            continue
        types = [t for t in ptypes.get(name.lower(), "{}").strip("{}").split(",") if t]
        if len(types) != nparams(s, i):
            fail("%s: %d parameters in PostgreSQL, SQLite's text numbers %d"
                 % (name, len(types), nparams(s, i)))
        cols = [line.split("\x1f")[-1] for line in sec.get(i + 1, []) if "\x1f" in line]
        result_types[name] = cols
        for k, t in enumerate(types):
            if t in ("unknown", "boolean"):
                fail("%s: parameter $%d is %s" % (name, k + 1, t))
        for k, t in enumerate(cols):
            if t in ("unknown", "boolean"):
                fail("%s: result column %d is %s" % (name, k + 1, t))
        if verbose:
            print("%-22s (%s) -> (%s)%s" % (name, ", ".join(types), ", ".join(cols),
                                             "" if s["pg"][i] is None else "  [stg_sql_pg]"))
    return result_types


# ---- the same statements on SQLite and PostgreSQL ----------------------------------------

def f64(*v):
    return struct.pack("<%dd" % len(v), *v)


def u16(*v):
    return struct.pack("<%dH" % len(v), *v)


def i64(*v):
    return struct.pack("<%dq" % len(v), *v)


def calib(cid, col, row, r, supersedes, changed_by, reason, map_="recommended", s_res=None,
          note=None, fit=1):
    """STG_CALIB_INSERT's parameters"""
    return (cid, 1, col, row, r, f64(*[1.0 + k / 8 for k in range(r * r)]),
            f64(*[0.01 * (k + 1) for k in range(r * r)]), 1.25, 0.98, "ok", 1, fit, "paper",
            0.65, 0.5, 0.79, "1.2.3", 8000 + cid, supersedes, changed_by, reason, map_, s_res,
            note)


# (statement, parameters); the ids are the ones a new database gives, the same in both
SCENARIO = [
    ("STG_USER_VERSION", ()),
    ("STG_SENSOR_INSERT", ("IMX", "A1", 640, 480, 5.86, 0.25, 2.5, 100.0, 4095.0, 1000)),
    ("STG_SENSOR_INSERT", ("IMX", "A2", 320, 240, 3.45, 1.0 / 3, 0.0, -2.5, 65535.0, 1001)),
    ("STG_SENSOR_INSERT", ("IMX", "A1", 1, 1, 1.0, 1.0, 1.0, 1.0, 1.0, 1)),  # UNIQUE
    ("STG_SENSOR_INSERT", ("", "A3", 1, 1, 1.0, 1.0, 1.0, 1.0, 1.0, 1)),  # CHECK
    ("STG_SENSOR_GET", (2,)),
    ("STG_SENSOR_FIND", ("IMX", "A2")),
    ("STG_SENSOR_FIND", ("IMX", "a2")),
    ("STG_SENSOR_LIST", (-1, 0)),
    ("STG_SENSOR_LIST", (1, 1)),
    ("STG_SENSOR_LIST", (5, -3)),
    ("STG_SENSOR_COUNT", ()),
    ("STG_SCAN_INSERT", (1, 100, 200, 0.65, 0.5, 0.79, 3, 0.25, 3, 2, 1000.0, 4, 2000)),
    ("STG_SCAN_INSERT", (2, 5, 6, 0.65, 0.5, 0.79, 1, 0.5, 1, 1, 10.5, 2, 2001)),
    ("STG_SCAN_INSERT", (1, 100, 200, 0.65, 0.5, 0.79, 3, 0.25, 4, 2, 1000.0, 4, 2002)),
    ("STG_SCAN_INSERT", (7, 100, 200, 0.65, 0.5, 0.79, 3, 0.25, 3, 2, 1000.0, 4, 2002)),
    ("STG_SCAN_GET", (1,)),
    ("STG_SCAN_COUNT", (None, None)),
    ("STG_SCAN_COUNT", (1, None)),
    ("STG_SCAN_COUNT", (None, "queued")),
    ("STG_SCAN_COUNT", (2, "running")),
    ("STG_SCAN_LIST", (None, None, -1, 0)),
    ("STG_SCAN_LIST", (1, "queued", 10, 0)),
    ("STG_SCAN_LIST", (None, None, 1, 1)),
    ("STG_SCAN_SET_STATE", (1, "running", None, 3000)),
    ("STG_SCAN_SET_STATE", (1, "running", None, 3500)),
    ("STG_SCAN_SET_STATE", (2, "bogus", None, 3500)),
    ("STG_SCAN_GET", (1,)),
    ("STG_SCAN_ADD_POINT", (1,)),
    ("STG_SCAN_SET_SETUP", (1, '{"centre_um": [1.5, 2, 3], "gain": 0.25}')),
    ("STG_SCAN_SET_SETUP", (2, "not json")),
    ("STG_SCAN_GET_SETUP", (1,)),
    ("STG_SCAN_GET_SETUP", (2,)),
    ("STG_FRAME_INSERT", (1, 0, 1.5, 2.5, 3.5, 1000.0, 4000, f64(*range(9)), u16(*range(18)))),
    ("STG_FRAME_INSERT", (1, 1, -1.5, 2.75, 3.5, 999.5, 4001, f64(*[k / 7 for k in range(9)]),
                          u16(*[65535 - k for k in range(18)]))),
    ("STG_FRAME_INSERT", (1, 1, 0.0, 0.0, 0.0, 1.0, 4002, f64(0.0), u16(0))),  # UNIQUE
    ("STG_FRAME_TIMES_INSERT", (1, 0, i64(10 ** 15, -3), None)),
    ("STG_FRAME_TIMES_INSERT", (1, 1, b"\0" * 7, None)),  # CHECK
    ("STG_FRAME_TIMES_INSERT", (1, 1, i64(1, 2), i64(2 ** 62, 5))),
    ("STG_FRAME_TIMES_GET", (1, 0)),
    ("STG_FRAME_TIMES_GET", (1, 1)),
    ("STG_FRAME_GET", (1, 1)),
    ("STG_FRAME_HEAD", (1, 1)),
    ("STG_FRAME_LAST", (1,)),
    ("STG_FRAME_LAST", (2,)),
    ("STG_FRAME_RASTER", (1, 9)),
    ("STG_FRAME_RASTER", (1, 69)),  # the last 4 bytes only
    ("STG_FRAME_RASTER", (1, 100)),  # past the end: empty
    ("STG_FRAME_MEANS", (1,)),
    ("STG_JOB_INSERT", ("scan", '{"scan": 1}', 5000, 1, "A")),
    ("STG_JOB_INSERT", ("fit", '{"pixels": "all", "map": "shrunk"}', 5001, 1, None)),
    ("STG_JOB_INSERT", ("fit", '{"pixels": [[0, 0]]}', 5002, 1, None)),
    ("STG_JOB_INSERT", ("ptc", "[1, 2]", 5003, None, "B")),
    ("STG_JOB_GET", (2,)),
    ("STG_JOB_GET", (3,)),
    ("STG_JOB_GET", (4,)),
    ("STG_JOB_NEXT", ("fit", None, None, "A")),
    ("STG_JOB_NEXT", ("ptc", "scan", None, "A")),
    ("STG_JOB_NEXT", ("ptc", None, None, "A")),
    ("STG_JOB_NEXT", ("ptc", None, None, "B")),
    ("STG_JOB_NEXT", (None, None, None, None)),
    ("STG_JOB_START", (2, 6000, "A")),
    ("STG_JOB_START", (2, 6001, "A")),
    ("STG_JOB_HEARTBEAT", (2, 6100, 0.25, 1, "A")),
    ("STG_JOB_HEARTBEAT", (2, 6150, 0.3, 1, "B")),
    ("STG_JOB_HEARTBEAT", (2, 6160, 0.3, 1, None)),
    ("STG_JOB_STEP", (2, 1, 2, 0.5, 6200, "A")),
    ("STG_JOB_STEP", (2, 1, 3, 0.75, 6300, "A")),
    ("STG_JOB_STEP", (2, 2, 3, 0.75, 6300, "B")),
    ("STG_FIT_INSERT", (1, 0, 0, "paper", 2, 3, 1.5, 0.01, '{"sweep": []}', 7000)),
    ("STG_FIT_INSERT", (1, 1, -1, "shot+read", None, None, None, None, "{}", 7001)),
    ("STG_FIT_INSERT", (None, 0, 0, "paper", 1, 1, None, None, "[]", 7002)),
    ("STG_FIT_INSERT", (1, 0, 0, "paper", 1, 1, None, None, "[", 7003)),  # CHECK (JSON)
    ("STG_FIT_SET_JOB", (1, 2)),
    ("STG_FIT_SET_JOB", (2, 2)),
    ("STG_FIT_SET_JOB", (3, 99)),  # FOREIGN KEY
    ("STG_JOB_SET_FIT", (2, 2)),
    ("STG_JOB_GET", (2,)),
    ("STG_JOB_COUNT", (None, None, None)),
    ("STG_JOB_COUNT", ("fit", None, None)),
    ("STG_JOB_COUNT", (None, "running", 1)),
    ("STG_JOB_COUNT", ("scan", "queued", 2)),
    ("STG_JOB_LIST", (None, None, None, -1, 0)),
    ("STG_JOB_LIST", ("fit", "running", 1, 10, 0)),
    ("STG_JOB_LIST", (None, None, None, 2, 1)),
    ("STG_JOB_RELEASE", (2, "B")),
    ("STG_JOB_RELEASE", (2, "A")),
    ("STG_JOB_RELEASE", (2, "A")),
    ("STG_JOB_STATE", (2,)),
    ("STG_JOB_START", (2, 6500, "A")),
    ("STG_JOB_START", (3, 6500, None)),
    ("STG_JOB_REQUEUE", (6400, None)),
    ("STG_JOB_REQUEUE", (6500, "B")),
    ("STG_JOB_REQUEUE", (6500, "A")),
    ("STG_JOB_REQUEUE", (6500, None)),
    ("STG_JOB_START", (2, 6600, "A")),
    ("STG_JOB_START", (3, 6600, "C")),
    ("STG_JOB_ABANDON", (6600, 0, 6700, None)),
    ("STG_JOB_ABANDON", (6600, 3, 6700, "A")),
    ("STG_JOB_ABANDON", (6600, 2, 6700, "B")),
    ("STG_JOB_ABANDON", (6600, 2, 6700, None)),
    ("STG_JOB_GET", (2,)),
    ("STG_JOB_LIST", ("fit", None, 1, 5, 0)),
    ("STG_JOB_START", (4, 6800, None)),
    ("STG_JOB_FINISH", (4, "done", None, 6900, "A")),
    ("STG_JOB_FINISH", (4, "done", None, 6900, None)),
    ("STG_JOB_FINISH", (4, "done", None, 6950, None)),
    ("STG_JOB_GET", (4,)),
    ("STG_JOB_CANCEL", (3, 7000)),
    ("STG_JOB_INSERT", ("fit", "{}", 7001, 2, None)),
    ("STG_JOB_CANCEL", (5, 7002)),
    ("STG_JOB_STATE", (5,)),
    # refused: last, as PostgreSQL's identity (unlike SQLite's rowid) has used an id for each
    ("STG_JOB_INSERT", ("fit", "{bad", 5004, 1, None)),  # CHECK (JSON)
    ("STG_JOB_INSERT", ("other", "{}", 5004, 1, None)),  # CHECK
    ("STG_JOB_INSERT", ("fit", "{}", 5004, 9, None)),  # FOREIGN KEY
    ("STG_FIT_MAP_INSERT", (1, 1, 100, 200, 2, f64(1, 1.5, 0.5, 1), f64(0.1, 0.1, 0.2, 0.1),
                            1.25, 0.98, "ok", 0.65, 0.5, 0.79, "1.2.3", "recommended", None,
                            None)),
    ("STG_FIT_MAP_INSERT", (2, 1, 101, 199, 1, f64(1), f64(0.5), None, None, "ok", None, None,
                            None, "1.2.3", "kriged", f64(0.1), "no signal")),
    ("STG_FIT_MAP_INSERT", (3, 1, 1, 1, 2, f64(1), f64(0.5), None, None, "ok", None, None,
                            None, "1.2.3", "kriged", None, None)),  # CHECK (size)
    ("STG_FIT_MAP_INSERT", (3, 1, 1, 1, 1, f64(1), f64(0.5), None, None, "ok", None, None,
                            None, "1.2.3", "other", None, None)),  # CHECK (map)
    ("STG_FIT_MAP_INSERT", (3, 1, 1, 1, 1, f64(1), f64(0.5), None, None, "ok", None, None,
                            None, "1.2.3", "shrunk", None, "")),  # CHECK (map_note)
    ("STG_FIT_MAP_GET", (1,)),
    ("STG_FIT_MAP_GET", (2,)),
    ("STG_FIT_MAP_GET", (3,)),
    ("STG_FIT_MAP_GET", (99,)),
    ("STG_FIT_GET", (1,)),
    ("STG_FIT_COUNT", (1,)),
    ("STG_FIT_LIST", (1, -1, 0)),
    ("STG_FIT_LIST", (1, 1, 1)),
    ("STG_BEGIN_WRITE", ()),
    ("STG_CALIB_CURRENT_ID", (1, 100, 200)),
    ("STG_CALIB_NEXT_ID", ()),
    ("STG_CALIB_INSERT", calib(1, 100, 200, 2, None, "ipsd", "automatic fit of scan 1")),
    ("STG_COMMIT", ()),
    ("STG_BEGIN_WRITE", ()),
    ("STG_CALIB_CURRENT_ID", (1, 100, 200)),
    ("STG_CALIB_NEXT_ID", ()),
    ("STG_CALIB_SUPERSEDE", (1, 2)),  # to a row not there yet: the deferred foreign key
    ("STG_CALIB_INSERT", calib(2, 100, 200, 1, 1, "api", "promoted", "shrunk", f64(0.5),
                               "why not", fit=2)),
    ("STG_COMMIT", ()),
    ("STG_BEGIN_WRITE", ()),
    ("STG_CALIB_INSERT", calib(3, 101, 199, 3, None, "api", "other pixel")),
    ("STG_COMMIT", ()),
    ("STG_BEGIN_WRITE", ()),
    ("STG_CALIB_SUPERSEDE", (3, 99)),  # the deferred foreign key fails at COMMIT
    ("STG_COMMIT", ()),
    ("STG_ROLLBACK", ()),
    ("STG_BEGIN_WRITE", ()),
    ("STG_CALIB_INSERT", calib(4, 100, 200, 1, None, "api", "a second current")),  # UNIQUE
    ("STG_ROLLBACK", ()),
    ("STG_CALIB_INSERT", calib(4, 100, 200, 2, None, "api", "bad", s_res=f64(1))),  # CHECK
    ("STG_CALIB_GET", (1,)),
    ("STG_CALIB_GET", (2,)),
    ("STG_CALIB_CURRENT", (1, 100, 200)),
    ("STG_CALIB_CURRENT_ID", (1, 100, 200)),
    ("STG_CALIB_HISTORY", (1, 100, 200)),
    ("STG_FIT_GET", (1,)),
    ("STG_FIT_GET", (2,)),
    ("STG_CALIB_COUNT", (None,) * 8 + (0,)),
    ("STG_CALIB_COUNT", (None,) * 8 + (1,)),
    ("STG_CALIB_COUNT", (1, "IMX", 100, 100, 200, 200, 8001, "ok", 0)),
    ("STG_CALIB_COUNT", (None, "nope") + (None,) * 6 + (0,)),
    ("STG_CALIB_SEARCH", (None,) * 8 + (0, -1, 0)),
    ("STG_CALIB_SEARCH", (None,) * 8 + (1, 1, 1)),
    ("STG_CALIB_SEARCH", (1, "IMX", 0, 100, 0, 200, 8002, None, 0, 10, 0)),
    ("STG_CALIB_NEXT_ID", ()),
    ("STG_PTC_INSERT", (1, 1.25, 2.5, 100.5, 4000.0, 0.75, '{"K": 0.8}', 4, 9000)),
    ("STG_PTC_INSERT", (1, 1.5, 2.0, None, None, None, "{}", None, 9001)),
    ("STG_PTC_INSERT", (1, 1.5, 2.0, None, None, None, "{", None, 9002)),  # CHECK (JSON)
    ("STG_PTC_INSERT", (1, 0.0, 2.0, None, None, None, "{}", None, 9002)),  # CHECK
    ("STG_PTC_GET", (1,)),
    ("STG_PTC_HISTORY", (1, -1)),
    ("STG_PTC_HISTORY", (1, 1)),
    ("STG_PTC_HISTORY", (2, 5)),
    ("STG_JOB_START", (1, 9100, "A")),
    ("STG_JOB_FINISH", (1, "failed", "camera lost", 9200, "A")),
    ("STG_SCAN_SET_STATE", (1, "failed", "camera lost", 9200)),
    ("STG_SCAN_RESUME", (1,)),
    ("STG_SCAN_RESUME", (1,)),
    ("STG_JOB_RESUME", (1,)),
    ("STG_JOB_RESUME", (1,)),
    ("STG_SCAN_GET", (1,)),
    ("STG_JOB_GET", (1,)),
    ("STG_SCAN_CANCEL", (2, 9300)),
    ("STG_SCAN_CANCEL", (2, 9400)),
    ("STG_SCAN_SET_STATE", (2, "done", None, 9500)),
    ("STG_BEGIN_READ", ()),
    ("STG_SCAN_LIST", (None, "cancelled", -1, 0)),
    ("STG_FRAME_LAST", (1,)),
    ("STG_COMMIT", ()),
    ("STG_USER_VERSION", ()),
    ("STG_PAGE_COUNT", ()),
    ("STG_FREELIST_COUNT", ()),
]
# sizes that are not the same thing in the two databases: compared as integers only
SIZE_ONLY = {"STG_PAGE_COUNT", "STG_FREELIST_COUNT"}
TAG = re.compile(r"(INSERT \d+|UPDATE|DELETE) (\d+)")


def run_sqlite(s):
    """[(error or None, rows, changes)] of SCENARIO on a new SQLite database"""
    db = sqlite3.connect(":memory:", isolation_level=None)
    for sql in s["mig"]:
        db.executescript(sql)
    db.execute("PRAGMA foreign_keys = ON")
    got = []
    for name, params in SCENARIO:
        before = db.total_changes
        try:
            rows = db.execute(s["sql"][s["ids"].index(name)], params).fetchall()
            got.append((None, rows, db.total_changes - before))
        except sqlite3.Error as e:
            got.append((str(e), None, None))
    db.close()
    return got


def run_pg(pg, s):
    ids = s["ids"]
    sc = Script()
    sc.add("\\pset null <NULL>")
    sc.add("\\set VERBOSITY verbose")  # errors begin with their SQLSTATE
    used = sorted({ids.index(name) for name, _ in SCENARIO})
    for i in used:
        if not is_transaction(s["sql"][i]):
            sc.add("PREPARE %s AS %s;" % (ids[i].lower(), pg_text(s, i)), "PREPARE " + ids[i])
    for k, (name, params) in enumerate(SCENARIO):
        i = ids.index(name)
        sc.mark(k)
        if is_transaction(s["sql"][i]):
            for sql in driver_runs(pg_text(s, i)):
                sc.add(sql + ";", k)
        else:
            sc.add(execute(name, params) + ";", k)
    out, err = pg.script(sc.text())
    errs = sc.errors(err)
    sec = sections(out)
    got = []
    for k, (name, _) in enumerate(SCENARIO):
        if k in errs:
            got.append((errs[k], None, None))
            continue
        if is_transaction(s["sql"][ids.index(name)]):
            got.append((None, [], 0))  # the write lock's SELECT prints a row of its own
            continue
        rows, changes = [], 0
        for line in sec.get(k, []):
            m = TAG.fullmatch(line)
            if m:
                changes = int(m.group(2))
            elif line not in ("BEGIN", "COMMIT", "ROLLBACK"):
                rows.append(line.split("\x1f"))
        got.append((None, rows, changes))
    return got, {t: e for t, e in errs.items() if isinstance(t, str)}


def same_value(lite, text):
    """SQLite's value against PostgreSQL's text of it, as the driver will read it"""
    if lite is None:
        return text == "<NULL>"
    if text == "<NULL>":
        return False
    if isinstance(lite, bytes):
        return text == "\\x" + lite.hex()
    if isinstance(lite, int):  # read with an integer reader: must be one
        return re.fullmatch(r"-?\d+", text) is not None and int(text) == lite
    if isinstance(lite, float):
        try:
            return float(text) == lite
        except ValueError:
            return False
    return text == lite


def constraint_kind(lite_error, pg_error):
    """what each database says broke: the kinds storage.c maps to different errnos"""
    lite = next((k for k, w in (("unique", "UNIQUE constraint"), ("foreign key", "FOREIGN KEY"),
                                ("check", "CHECK constraint"), ("not null", "NOT NULL"))
                 if w in lite_error), "other: " + lite_error)
    code = pg_error.split(":")[0]
    pg = {"23505": "unique", "23503": "foreign key", "23514": "check",
          "23502": "not null"}.get(code, "other: " + pg_error)
    return lite, pg


INTEGER_TYPES = ("bigint", "integer", "smallint")


def check_scenario(pg, s, result_types, verbose):
    """result_types: {statement: PostgreSQL's result column types} (check_prepare)"""
    lite = run_sqlite(s)
    pgr, prep_errs = run_pg(pg, s)
    for tag, msg in prep_errs.items():
        fail("scenario: %s: %s" % (tag, msg))
    for k, ((name, params), a, b) in enumerate(zip(SCENARIO, lite, pgr)):
        what = "scenario step %d, %s%s" % (k, name, tuple(
            p if not isinstance(p, bytes) else "<%d bytes>" % len(p) for p in params))
        if (a[0] is None) != (b[0] is None):
            fail("%s: SQLite %s, PostgreSQL %s" % (what, a[0] or "ok", b[0] or "ok"))
            continue
        if a[0] is not None:
            kinds = constraint_kind(a[0], b[0])
            if kinds[0] != kinds[1]:
                fail("%s: SQLite refuses it as %s, PostgreSQL as %s" % (what, *kinds))
            elif verbose:
                print("both refuse %s\n    SQLite: %s\n    PostgreSQL: %s" % (what, a[0], b[0]))
            continue
        if a[2] != b[2]:
            fail("%s: changed %d rows in SQLite, %d in PostgreSQL" % (what, a[2], b[2]))
        rows_a, rows_b = a[1], b[1]
        if len(rows_a) != len(rows_b):
            fail("%s: %d rows from SQLite, %d from PostgreSQL:\n    %r\n    %r"
                 % (what, len(rows_a), len(rows_b), rows_a, rows_b))
            continue
        for ra, rb in zip(rows_a, rows_b):
            if len(ra) != len(rb):
                fail("%s: %d columns from SQLite, %d from PostgreSQL" % (what, len(ra), len(rb)))
                break
            types = result_types.get(name, [])
            for c, (va, vb) in enumerate(zip(ra, rb)):
                ok = (re.fullmatch(r"-?\d+", vb) is not None) if name in SIZE_ONLY \
                    else same_value(va, vb)
                if not ok:
                    fail("%s: column %d: SQLite %r, PostgreSQL %r" % (what, c + 1, va, vb))
                # an integer in SQLite is read as one: PostgreSQL's column must be an integer
                # type, whose text stays digits at any size (a double's is 1e+15)
                if isinstance(va, int) and c < len(types) and types[c] not in INTEGER_TYPES:
                    fail("%s: column %d is an integer in SQLite, %s in PostgreSQL"
                         % (what, c + 1, types[c]))
        if verbose:
            print("same: %s: %d rows, %d changed" % (what, len(rows_a), a[2]))


# ---- main ---------------------------------------------------------------------------------

def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("uri", nargs="?", help="postgresql://user@host:port/db")
    ap.add_argument("--uri-file", help="a file holding the URI (tests/pg_server.sh's DIR/uri)")
    ap.add_argument("-v", "--verbose", action="store_true")
    a = ap.parse_args()
    uri = a.uri
    if not uri:
        if not a.uri_file:
            ap.error("a URI or --uri-file is needed")
        if not os.path.exists(a.uri_file):
            if not pg_installed():
                print("pg_sql_check: PostgreSQL is not installed: skipped")
                return 77
            sys.exit("pg_sql_check: no %s: the server did not start (tests/pg_server.sh)"
                     % a.uri_file)
        with open(a.uri_file, encoding="utf-8") as f:
            uri = f.read().strip()
    psql = find_psql()
    if not psql:
        if not pg_installed():
            print("pg_sql_check: PostgreSQL is not installed: skipped")
            return 77
        sys.exit("pg_sql_check: psql not found")

    s = load_sql()
    static_checks(s)
    base = "ipsd_sql_check_%d" % os.getpid()
    pg = Pg(psql, uri, None)
    r = pg.command("SELECT version()", schema=False)
    if r.returncode:
        sys.exit("pg_sql_check: cannot connect to %s: %s" % (uri, r.stderr.strip()))
    print("pg_sql_check: %s, %d statements (%d in PostgreSQL's own text), %d migrations"
          % (r.stdout.strip().split(",")[0], len(s["ids"]),
             sum(t is not None for t in s["pg"]), len(s["pg_mig"])))
    try:
        if check_migrations(pg, s, base):
            check_json(Pg(psql, uri, base + "_b"), a.verbose)
            types = check_prepare(Pg(psql, uri, base + "_a"), s, a.verbose)
            err = new_schema(pg, base + "_c", s)
            if err:
                fail("scenario schema: " + err)
            else:
                check_scenario(Pg(psql, uri, base + "_c"), s, types, a.verbose)
    finally:
        pg.command("; ".join("DROP SCHEMA IF EXISTS %s_%s CASCADE" % (base, x) for x in "abc"),
                   schema=False)
    if FAILURES:
        print("pg_sql_check: %d failures" % len(FAILURES), file=sys.stderr)
        return 1
    print("pg_sql_check: ok (%d scenario steps the same in SQLite and PostgreSQL)"
          % len(SCENARIO))
    return 0


if __name__ == "__main__":
    sys.exit(main())
