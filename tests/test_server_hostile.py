#!/usr/bin/env python3
"""test_server_hostile.py IPSD: requests an attacker (or a broken client) sends to a real ipsd on
loopback, each a defect found by attacking it, each answered with the JSON error body
of docs/contracts.md and nothing stored changed:
  - text that is not valid UTF-8 in a query value, a path, or a member name cut off by the
    message buffer keeps the error body whole (message and field);
  - a FIFO in the web directory is refused (404) without blocking an HTTP thread;
  - %00 in a path or a query value does not cut it short (scan 1%00junk is not scan 1);
  - GET /api/sensors pages like every list (?limit=, ?offset=, 422 out of range);
  - a subnormal or sub-0.1 um pitch is refused;
  - a scan that would store more than --max-scan-bytes is refused (422 naming raster);
  - a request line of HTTP/2.0 gets 505 (libmicrohttpd's own answer), HTTP/1.0 is served;
  - a request target over 8 KiB gets 414 and header fields over 16 KiB get 431, with the JSON
    error (defect 11); only what overflows libmicrohttpd's 64 KiB buffer gets its own answer."""
import json
import os
import socket
import sys

import ipsd_http
from ipsd_http import Db, Ipsd


def raw(port, data, timeout=ipsd_http.DEADLINE_S):
    """Sends bytes on a fresh connection and returns (status, body) of the answer."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(data)
        buf = b""
        while True:
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
            head, sep, body = buf.partition(b"\r\n\r\n")
            if sep:
                length = [int(h.split(b":")[1]) for h in head.split(b"\r\n")
                          if h.lower().startswith(b"content-length:")]
                if length and len(body) >= length[0]:
                    break
    head, _, body = buf.partition(b"\r\n\r\n")
    return int(head.split(b" ")[1]), body


def test(c, t, argv, daemons):
    exe = argv[1]
    d = Ipsd(exe, t)
    daemons.append(d)
    web = os.path.join(t, "web")
    os.makedirs(web)
    with open(os.path.join(web, "index.html"), "w") as f:
        f.write("<h1>ipsd</h1>\n")
    os.mkfifo(os.path.join(web, "pipe.html"))
    # one HTTP thread: a request that blocked it would block every later one
    # --max-scan-bytes 1 MiB; a scan is held at its first point (then cancelled)
    d.start("--web", web, "--http-threads", "1", "--max-scan-bytes", "1048576",
            failpoints="scan.point=hold@1")
    db = Db(d.db)

    def counts():
        return db.one("SELECT (SELECT count(*) FROM sensors), (SELECT count(*) FROM scans), "
                      "(SELECT count(*) FROM fits), (SELECT count(*) FROM calibrations)")

    sensors = []
    for k in range(3):
        r = d.post("/api/sensors", {"model": "IMX-H", "serial": "hostile-%d" % k})
        c.status(r, 201, "create sensor %d" % k)
        sensors.append(r.json()["id"])
    before = counts()

    # ---- UTF-8: the error body stays whole ----
    r = d.get("/api/scans?limit=%ff")
    c.error(r, 400, "limit", "limit=%ff: 400 naming limit")
    c.ok("limit" in r.json()["error"]["message"], "limit=%ff: the message is kept")
    r = d.get("/api/scans/%ff%fe")
    c.status(r, 404, "a path of invalid UTF-8: 404")
    c.ok(r.json()["error"]["code"] == "not_found", "a path of invalid UTF-8: the JSON body")
    # a member name longer than the message buffer, cut in the middle of a two-byte character
    key = "\u00e9" * 200
    r = d.post("/api/sensors", {"model": "IMX-H", "serial": "x", key: 1})
    c.status(r, 422, "unknown member of 200 x e-acute: 422")
    e = r.json()["error"]
    c.ok(e["code"] == "unknown_field" and e["field"].startswith("\u00e9" * 10),
         "the unknown member is named (valid UTF-8, cut short): %r" % e.get("field", "")[:20])

    # ---- a FIFO in the web directory ----
    r = d.get("/pipe.html")
    c.error(r, 404, "", "a FIFO in the web directory: 404")
    r = d.get("/api/health")
    c.status(r, 200, "after the FIFO the (single) HTTP thread still answers")

    # ---- %00 does not cut a path or a value short ----
    r = d.get("/api/sensors/%d" % sensors[0])
    c.status(r, 200, "sensor %d exists" % sensors[0])
    r = d.get("/api/sensors/%d%%00junk" % sensors[0])
    c.status(r, 404, "sensor N%00junk is not sensor N")
    r = d.get("/index.html")
    c.status(r, 200, "index.html is served")
    r = d.get("/index.html%00.png")
    c.error(r, 404, "", "index.html%00.png is not index.html")
    r = d.get("/api/scans?limit=5%00")
    c.error(r, 400, "limit", "limit=5%00 is not 5")

    # ---- sensors are a page ----
    r = d.get("/api/sensors?limit=1&offset=1")
    c.status(r, 200, "sensors page")
    p = r.json()
    c.eq((p["total"], p["limit"], p["offset"], [s["id"] for s in p["items"]]),
         (3, 1, 1, [sensors[1]]), "sensors ?limit=1&offset=1: the second sensor, total 3")
    r = d.get("/api/sensors")
    c.eq((r.json()["limit"], len(r.json()["items"])), (50, 3), "sensors: default limit 50")
    c.error(d.get("/api/sensors?limit=0"), 422, "limit", "sensors ?limit=0: 422 like scans")
    c.error(d.get("/api/sensors?offset=-1"), 422, "offset", "sensors ?offset=-1: 422")

    # ---- a pitch no sensor has ----
    for pitch in ("5e-324", "1e-310", "0.05", "0"):
        body = '{"model": "IMX-H", "serial": "pitch-%s", "pitch_um": %s}' % (pitch, pitch)
        r = d.req("POST", "/api/sensors", body, {"Content-Type": "application/json"})
        c.error(r, 422, "pitch_um", "pitch_um %s: 422" % pitch)

    # ---- HTTP versions ----
    # libmicrohttpd 0.9.75 answers these itself (its body is HTML; no option replaces it)
    st, body = raw(d.port, b"GET /api/health HTTP/2.0\r\nHost: x\r\n\r\n")
    c.eq(st, 505, "HTTP/2.0 request line: 505, not 200")
    st, body = raw(d.port, b"GET /api/health HTTP/1.0\r\n\r\n")
    c.eq(st, 200, "HTTP/1.0 still answered")

    # ---- a long target, large header fields: ipsd's own limits answer with the JSON error ----
    # (8 KiB target, 16 KiB of header fields; libmicrohttpd's buffer, 64 KiB, is above both)
    def json_error(st, body, status, code, what):
        c.eq(st, status, what)
        try:
            e = json.loads(body)["error"]
        except ValueError:
            e = {}
        c.eq(e.get("code"), code, what + ": the JSON error body")

    st, body = raw(d.port, b"GET /api/health?" + b"a" * 8000 + b" HTTP/1.1\r\nHost: x\r\n\r\n")
    c.eq(st, 200, "a target just under 8 KiB is served")
    st, body = raw(d.port, b"GET /api/health?q=" + b"a" * 20000 + b" HTTP/1.1\r\nHost: x\r\n\r\n")
    json_error(st, body, 414, "uri_too_long", "a 20 kB query: 414")
    st, body = raw(d.port, b"GET /" + b"a" * 20000 + b" HTTP/1.1\r\nHost: x\r\n\r\n")
    json_error(st, body, 414, "uri_too_long", "a 20 kB static path: 414")
    big = b"".join(b"X-Pad-%d: %s\r\n" % (k, b"b" * 1000) for k in range(20))
    st, body = raw(d.port, b"GET /api/health HTTP/1.1\r\nHost: x\r\n" + big + b"\r\n")
    json_error(st, body, 431, "header_fields_too_large", "20 kB of header fields: 431")
    st, body = raw(d.port, b"POST /api/sensors HTTP/1.1\r\nHost: x\r\n" + big +
                   b"Content-Type: application/json\r\nContent-Length: 2\r\n\r\n{}")
    json_error(st, body, 431, "header_fields_too_large", "a POST with them: 431, nothing stored")
    # beyond libmicrohttpd's buffer it still answers itself (documented, docs/api.md)
    st, body = raw(d.port, b"GET /api/health?q=" + b"a" * 100000 + b" HTTP/1.1\r\n\r\n")
    c.eq(st, 414, "a 100 kB target: libmicrohttpd's own 414")
    c.status(d.get("/api/health"), 200, "and ipsd still answers")

    # ---- what one scan may store ----
    def scan(raster):
        return d.post("/api/scans", {"sensor_id": sensors[0], "poi": {"col": 100, "row": 100},
                                     "raster": raster})
    # the attack: 101 x 101 pixels at 1 um, 99 x 99 sub-frames of 1000 frames
    r = scan({"area_px": 101, "step_um": 1, "sub_px": 99, "frames": 1000})
    c.error(r, 422, "raster", "a 7 TB scan: 422 naming raster")
    c.ok("max-scan-bytes" in r.json()["error"]["message"], "the message names --max-scan-bytes")
    # the paper's raster, 51 x 51 points of 5 x 5 pixels x 12 frames: 2601 x (25 x 12 x 2 + 25 x 8)
    # bytes = 2.08 MB, over the 1 MiB limit
    r = scan({"area_px": 5, "step_um": 0.6, "sub_px": 5, "frames": 12})
    c.error(r, 422, "raster", "the paper's 2 MB scan over a 1 MiB limit: 422")
    c.eq(counts(), before, "nothing stored changed")
    # one pixel at 0.6 um (at most 11 x 11 points) of 3 x 3 pixels x 1 frame: 121 x 90 bytes
    r = scan({"area_px": 1, "step_um": 0.6, "sub_px": 3, "frames": 1})
    c.status(r, 202, "an 11 kB scan under the limit is accepted (queued)")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")
    db.close()


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
