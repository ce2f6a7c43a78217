#!/usr/bin/env python3
"""test_server_security.py IPSD: access control, CORS and the request log of a real ipsd:
  - token files hold several tokens, plain or as sha256:HEX (hashes made here by Python's
    hashlib, an independent SHA-256; `ipsd --hash-token` prints the same line);
  - a missing, wrong, truncated or extended token gets 401 with the JSON error body and
    WWW-Authenticate; a read token (--read-token) reads but gets 403 on a write; write tokens
    read and write; /api/health, /api/openapi.json and the dashboard's files stay open;
  - nothing was stored by a refused write (the database read with Python's sqlite3);
  - the request log has one line per request with method, path, status, bytes and ms, and never
    a token, a token's hash or a query string; a control character in a path cannot break a line;
  - no Access-Control-* header by default (and OPTIONS stays 405); with --cors-origin the allowed
    origin gets Access-Control-Allow-Origin and its preflight 204, another origin neither;
  - bad token configurations stop ipsd at start (exit 2, naming the option);
  - the event stream without a header (a browser's EventSource, reads closed): POST
    /api/events/ticket needs a read or write token and gives a ticket, GET /api/events?ticket=
    opens with it; a tampered ticket, a ticket on another read, and a ticket with a header of a
    wrong token get 401; no ticket is in the request log;
  - POST /api/jitter, which only computes, takes a read token when reads are closed and the
    write token when only writes are (never open when ipsd has tokens)."""
import hashlib
import os
import re
import subprocess
import sys
import urllib.parse

import ipsd_http
from ipsd_http import Db, Ipsd

WRITER_PLAIN = "w-Plain.7f3a9c"        # stored as itself in the write token file
WRITER_HASHED = "w-Hashed.51be02"      # stored only as sha256:HEX
READER = "r-Reader.c0ffee"             # the read token, stored as sha256:HEX
SECRETS = [WRITER_PLAIN, WRITER_HASHED, READER]


def sha_line(token):
    return "sha256:" + hashlib.sha256(token.encode()).hexdigest()


def bearer(token):
    return {"Authorization": "Bearer " + token}


def test(c, t, argv, daemons):
    exe = argv[1]
    # ---- ipsd --hash-token prints the line a token file may hold instead of the token ----
    r = subprocess.run([exe, "--hash-token"], input=READER + "\n", capture_output=True,
                       text=True, timeout=ipsd_http.DEADLINE_S)
    c.eq((r.returncode, r.stdout.strip()), (0, sha_line(READER)), "ipsd --hash-token")
    # docs/operations.md lists every flag of ipsd --help (its flag table is kept in step)
    usage = subprocess.run([exe, "--help"], capture_output=True, text=True,
                           timeout=ipsd_http.DEADLINE_S).stdout
    ops = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "operations.md")
    with open(ops) as f:
        documented = set(re.findall(r"^\| `(--[a-z-]+)", f.read(), re.M))
    flags = set(re.findall(r"^  (--[a-z-]+)", usage, re.M))
    c.ok(len(flags) > 20 and flags <= documented,
         "docs/operations.md lists every flag; missing: %s" % sorted(flags - documented))
    r = subprocess.run([exe, "--hash-token"], input="two words\n", capture_output=True,
                       text=True, timeout=ipsd_http.DEADLINE_S)
    c.eq(r.returncode, 2, "--hash-token refuses a token with a space")

    wfile, rfile = os.path.join(t, "write.tokens"), os.path.join(t, "read.tokens")
    with open(wfile, "w") as f:
        f.write("# the lab's writers\n%s\n\n  %s  \n" % (WRITER_PLAIN, sha_line(WRITER_HASHED)))
    with open(rfile, "w") as f:
        f.write(sha_line(READER).upper().replace("SHA256:", "sha256:") + "\n")
    log = os.path.join(t, "access.log")
    web = os.path.join(t, "web")
    os.makedirs(web)
    with open(os.path.join(web, "index.html"), "w") as f:
        f.write("<h1>ipsd</h1>\n")

    # ---- bad configurations: exit 2 naming the option ----
    empty = os.path.join(t, "empty.tokens")
    with open(empty, "w") as f:
        f.write("# nothing\n\n")
    for args, word in ((["--read-token", rfile], "--token"), (["--token", empty], "empty"),
                       (["--cors-origin", "http://a.example/path"], "--cors-origin")):
        r = subprocess.run([exe, "--listen", "127.0.0.1:0", "--db", os.path.join(t, "x.db"),
                            *args], capture_output=True, text=True, timeout=ipsd_http.DEADLINE_S)
        c.ok(r.returncode == 2 and word in r.stderr, "%s: exit 2 naming %s (got %d: %s)"
             % (args, word, r.returncode, r.stderr.strip()))

    d = Ipsd(exe, t)
    daemons.append(d)
    d.start("--token", wfile, "--read-token", rfile, "--access-log", log, "--web", web)
    db = Db(d.db)

    # ---- reads ----
    for h, name in ((None, "no token"), (bearer("nope"), "a wrong token"),
                    (bearer(READER[:-1]), "the read token less its last character"),
                    (bearer(READER + "x"), "the read token with one more character"),
                    (bearer(sha_line(READER)), "the read token's hash line"),
                    ({"Authorization": "Basic " + READER}, "another scheme")):
        r = d.get("/api/sensors", headers=h)
        c.error(r, 401, "", "GET /api/sensors with " + name)
        c.eq(r.headers.get("WWW-Authenticate"), "Bearer", "401 names the scheme (%s)" % name)
    for tok, name in ((READER, "read"), (WRITER_PLAIN, "plain write"),
                      (WRITER_HASHED, "hashed write")):
        r = d.get("/api/sensors", headers=bearer(tok))
        c.status(r, 200, "GET /api/sensors with the %s token" % name)
        c.eq(r.json()["total"], 0, "an empty list (%s token)" % name)
    c.status(d.get("/api/sensors", headers={"Authorization": "bearer " + READER}), 200,
             "the scheme's name is case-insensitive")
    for path in ("/api/health", "/api/openapi.json", "/", "/index.html"):
        c.status(d.get(path), 200, "GET %s needs no token" % path)

    # ---- writes ----
    body = {"model": "IMX-S", "serial": "sec-1"}
    c.error(d.post("/api/sensors", body), 401, "", "POST without a token")
    c.error(d.post("/api/sensors", body, headers=bearer("nope")), 401, "", "POST, wrong token")
    r = d.post("/api/sensors", body, headers=bearer(READER))
    c.error(r, 403, "", "POST with the read token")
    c.eq(db.val("SELECT count(*) FROM sensors"), 0, "refused writes stored nothing")
    c.status(d.post("/api/sensors", body, headers=bearer(WRITER_HASHED)), 201,
             "POST with the hashed write token")
    c.status(d.post("/api/sensors", dict(body, serial="sec-2"), headers=bearer(WRITER_PLAIN)),
             201, "POST with the plain write token")
    c.eq(db.all("SELECT serial FROM sensors ORDER BY id"), [("sec-1",), ("sec-2",)],
         "the two sensors stored")
    c.error(d.post("/api/scans/1/cancel", headers=bearer(READER)), 403, "",
            "a write without a body with the read token")
    # a POST that only computes (jitter photometry on an inline map) is a read: the read token
    # will do, no token will not (reads are closed here)
    jit = {"map": {"r": 1, "S": [1]}, "pitch_um": 6, "psf": {"kind": "gauss", "sigma_um": 1},
           "jitter": {"rms_um": 0.1, "samples": 10}}
    c.error(d.post("/api/jitter", jit), 401, "", "POST /api/jitter without a token")
    c.status(d.post("/api/jitter", jit, headers=bearer(READER)), 200,
             "POST /api/jitter with the read token")

    # ---- the event stream with a ticket (reads closed) ----
    c.error(d.get("/api/events"), 401, "", "GET /api/events without a token")
    c.error(d.post("/api/events/ticket"), 401, "", "POST /api/events/ticket without a token")
    c.error(d.post("/api/events/ticket", headers=bearer("nope")), 401, "", "... a wrong token")
    tickets = []
    for tok, name in ((READER, "read"), (WRITER_HASHED, "write")):
        r = d.post("/api/events/ticket", headers=bearer(tok))
        c.status(r, 200, "a ticket with the %s token" % name)
        c.eq(r.headers.get("Cache-Control"), "no-store", "a ticket is never cached")
        b = r.json()
        c.ok(isinstance(b.get("ticket"), str) and b.get("expires_in_s") == 60,
             "the ticket and its lifetime: %r" % b)
        tickets.append(b.get("ticket") or "")
    q = urllib.parse.quote(tickets[0], safe="")
    s = ipsd_http.EventStream(d.port, "/api/events?ticket=" + q)
    c.eq((s.status, bool(s.ready)), (200, True), "GET /api/events?ticket= opens the stream")
    c.ok(s.content_type.startswith("text/event-stream"), "an event stream")
    s.close()
    t0 = tickets[0]
    flip = t0[:-1] + ("0" if t0[-1] != "0" else "1")
    later = str(int(t0.split(".")[0]) + 3600000) + "." + t0.split(".", 1)[1]
    for bad, name in ((flip, "a ticket with its MAC altered"),
                      (later, "a ticket with its expiry moved later"),
                      ("x" * 40, "a made-up ticket"), ("", "an empty ticket")):
        c.error(d.get("/api/events?ticket=" + urllib.parse.quote(bad, safe="")), 401, "",
                "GET /api/events with " + name)
    c.error(d.get("/api/sensors?ticket=" + q), 401, "", "a ticket opens nothing but the stream")
    c.error(d.get("/api/events?ticket=" + q, headers=bearer("nope")), 401, "",
            "a wrong token's header is not overridden by a ticket")
    c.error(d.post("/api/sensors?ticket=" + q, body), 401, "", "nor does a ticket write")

    # ---- CORS off by default ----
    r = d.get("/api/health", headers={"Origin": "http://lab.example"})
    c.eq([k for k in r.headers if k.lower().startswith("access-control")], [],
         "no Access-Control-* header by default")
    r = d.req("OPTIONS", "/api/sensors", headers={"Origin": "http://lab.example",
                                                  "Access-Control-Request-Method": "POST"})
    c.ok(r.status in (401, 405) and not [k for k in r.headers
                                         if k.lower().startswith("access-control")],
         "a preflight is not answered as one by default (status %d)" % r.status)

    # ---- the request log ----
    c.status(d.get("/api/sensors?token=%s&limit=5" % READER, headers=bearer(READER)), 200,
             "a secret in the query string")
    c.error(d.get("/api/x%0Ainjected%20200"), 404, "", "a path with a newline and a space")
    c.eq(d.stop_term(), 0, "SIGTERM: exit 0")
    with open(log) as f:
        text = f.read()
    lines = text.splitlines()
    pat = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z 127\.0\.0\.1 ([A-Z]+) (\S+) "
                     r"(\d{3}) (\d+|-) (\d+\.\d\d)ms( aborted)?$")
    parsed = [pat.match(l) for l in lines]
    c.ok(all(parsed), "every log line has time, client, method, path, status, bytes, ms: %r"
         % [l for l, m in zip(lines, parsed) if not m][:3])
    got = [(m.group(1), m.group(2), int(m.group(3))) for m in parsed if m]
    for want in (("GET", "/api/sensors", 401), ("GET", "/api/sensors", 200),
                 ("POST", "/api/sensors", 403), ("POST", "/api/sensors", 201),
                 ("POST", "/api/scans/1/cancel", 403), ("GET", "/api/health", 200),
                 ("GET", "/index.html", 200), ("OPTIONS", "/api/sensors", r.status)):
        c.ok(want in got, "a log line for %s %s %d" % want)
    c.eq(sum(1 for g in got if g == ("POST", "/api/sensors", 201)), 2, "one line per request")
    c.ok(("GET", "/api/x%0Ainjected%20200", 404) in got,
         "the newline and space in a path are escaped in its line")
    bytes_401 = [int(m.group(4)) for m in parsed if m and m.group(3) == "401"]
    c.ok(bytes_401 and all(b > 20 for b in bytes_401), "bytes of the error bodies logged")
    leaks = [s for s in SECRETS + [sha_line(s)[7:] for s in SECRETS] if s.lower() in
             (text + d.log_text()).lower()]
    c.eq(leaks, [], "no token nor token hash in the request log or ipsd's stderr")
    c.ok("limit=5" not in text and "token=" not in text, "no query string in the log")
    c.ok(not [x for x in tickets if x and x in text + d.log_text()] and "ticket=" not in text,
         "no ticket in the request log or ipsd's stderr")
    c.ok(("GET", "/api/events", 200) in got and ("POST", "/api/events/ticket", 200) in got,
         "the stream opened with a ticket and the ticket's request are logged (paths only)")

    # ---- CORS on; the default log on stderr ----
    d.start("--token", wfile, "--cors-origin", "http://lab.example")
    r = d.get("/api/health", headers={"Origin": "http://lab.example"})
    c.eq((r.headers.get("Access-Control-Allow-Origin"), r.headers.get("Vary")),
         ("http://lab.example", "Origin"), "the allowed origin gets Allow-Origin")
    r = d.get("/api/health", headers={"Origin": "http://evil.example"})
    c.eq(r.headers.get("Access-Control-Allow-Origin"), None, "another origin gets none")
    c.eq(d.get("/api/health").headers.get("Access-Control-Allow-Origin"), None,
         "a request without Origin gets none")
    pre = {"Origin": "http://lab.example", "Access-Control-Request-Method": "POST",
           "Access-Control-Request-Headers": "authorization, content-type"}
    r = d.req("OPTIONS", "/api/sensors", headers=pre)
    c.status(r, 204, "the preflight of the allowed origin (no token needed)")
    c.eq(r.headers.get("Access-Control-Allow-Origin"), "http://lab.example", "preflight origin")
    methods = [m.strip() for m in (r.headers.get("Access-Control-Allow-Methods") or "").split(",")]
    c.ok("POST" in methods and "GET" in methods, "preflight methods: %r" % methods)
    allowed = (r.headers.get("Access-Control-Allow-Headers") or "").lower()
    c.ok("authorization" in allowed and "content-type" in allowed,
         "preflight headers: %r" % allowed)
    r = d.req("OPTIONS", "/api/sensors", headers=dict(pre, Origin="http://evil.example"))
    c.eq(r.headers.get("Access-Control-Allow-Origin"), None, "no preflight grant for another origin")
    c.error(d.req("OPTIONS", "/api/nothing", headers=pre), 404, "", "preflight of an unknown path")
    r = d.post("/api/sensors", {"model": "IMX-S", "serial": "sec-3"},
               headers=dict(bearer(WRITER_PLAIN), Origin="http://lab.example"))
    c.status(r, 201, "a cross-origin write with the token")
    c.eq(r.headers.get("Access-Control-Allow-Origin"), "http://lab.example", "its Allow-Origin")
    # reads open, writes closed: jitter photometry (an HTTP thread for up to a second) is not
    # open to anyone, it takes the write token (docs/api.md, Conventions)
    c.status(d.get("/api/sensors"), 200, "reads are open with --token alone")
    c.error(d.post("/api/jitter", jit), 401, "", "POST /api/jitter without a token, reads open")
    c.error(d.post("/api/jitter", jit, headers=bearer("nope")), 401, "",
            "POST /api/jitter with a wrong token, reads open")
    c.status(d.post("/api/jitter", jit, headers=bearer(WRITER_PLAIN)), 200,
             "POST /api/jitter with the write token, reads open")
    c.eq(d.stop_term(), 0, "SIGTERM: exit 0")
    c.ok(re.search(r"Z 127\.0\.0\.1 POST /api/sensors 201 \d+ \d+\.\d\dms", d.log_text()),
         "without --access-log the lines go to stderr")
    c.ok(WRITER_PLAIN not in d.log_text(), "and hold no token")
    db.close()


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
