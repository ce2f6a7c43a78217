#!/usr/bin/env python3
"""test_server_flood.py IPSD: one address flooding ipsd with connections does not lock out the
others, attacked on loopback as an outsider would:
  - 1100 connections from 127.0.0.2 trickling an unfinished header, then 1100 event streams from
    127.0.0.2: /api/health from 127.0.0.1 still answers (--max-per-client, default 128, and a
    connection limit far above libmicrohttpd's 1020);
  - event streams beyond --max-subscribers get 503 with Retry-After, and a stream whose client
    went away is dropped at the next heartbeat, freeing its place;
  - a request whose headers trickle in, a byte at a time, is cut at --request-timeout even though
    it is never idle (libmicrohttpd's idle timeout never fires on it)."""
import resource
import socket
import sys
import time

import ipsd_http
from ipsd_http import Client, Ipsd, wait_for

FLOOD = 1100


def flood(port, request, n=FLOOD):
    """n connections from 127.0.0.2, each sending request (unfinished or not); returns them."""
    socks = []
    for _ in range(n):
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.bind(("127.0.0.2", 0))
        s.settimeout(ipsd_http.DEADLINE_S)
        try:
            s.connect(("127.0.0.1", port))
            s.sendall(request)
        except OSError:
            pass  # refused or reset: over the limit
        socks.append(s)
    return socks


def health(port):
    """GET /api/health on a fresh connection from 127.0.0.1 with a short deadline (a locked-out
    server fails the test instead of hanging it); the JSON or None."""
    c = Client(port, timeout=20)
    try:
        r = c.request("GET", "/api/health")
        return r.json() if r.status == 200 else None
    except OSError:
        return None
    finally:
        c.close()


def stream(port):
    """Opens GET /api/events from 127.0.0.1 and reads the status line and headers."""
    s = socket.create_connection(("127.0.0.1", port), timeout=ipsd_http.DEADLINE_S)
    s.sendall(b"GET /api/events HTTP/1.1\r\nHost: x\r\n\r\n")
    head = b""
    while b"\r\n\r\n" not in head:
        chunk = s.recv(4096)
        if not chunk:
            break
        head += chunk
    return s, head


def test(c, t, argv, daemons):
    exe = argv[1]
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    need = 2 * FLOOD + 200
    if soft < need:
        resource.setrlimit(resource.RLIMIT_NOFILE, (min(need, hard), hard))
    d = Ipsd(exe, t)
    daemons.append(d)
    d.start("--max-subscribers", "3")

    # ---- 1100 slow headers from one address ----
    socks = flood(d.port, b"GET /api/health HTTP/1.1\r\nX-Slow: 1\r\n")
    h = health(d.port)
    c.ok(h is not None, "after 1100 slow-header connections from 127.0.0.2, 127.0.0.1 is served")
    if h:
        c.ok(h["connections"] <= 128 + 2,
             "at most --max-per-client (128) of them are held: %d open" % h["connections"])
    for s in socks:
        s.close()

    # ---- 1100 event streams from one address ----
    socks = flood(d.port, b"GET /api/events HTTP/1.1\r\nHost: x\r\n\r\n")
    h = health(d.port)
    c.ok(h is not None, "after 1100 event streams from 127.0.0.2, 127.0.0.1 is served")
    for s in socks:
        s.close()
    # the streams that got in (at most --max-subscribers) go at their next heartbeat (1 s)
    c.ok(wait_for(lambda: (health(d.port) or {}).get("event_subscribers") == 0),
         "closed streams are dropped at the next heartbeat")

    # ---- the event-stream limit ----
    streams = [stream(d.port) for _ in range(3)]
    c.ok(all(b" 200 " in head.split(b"\r\n")[0] for _, head in streams), "3 streams: 200 each")
    s4, head = stream(d.port)
    status_line = head.split(b"\r\n")[0]
    c.ok(b" 503 " in status_line, "a 4th stream over --max-subscribers 3: 503 (%r)" % status_line)
    c.ok(b"\r\nretry-after: 5" in head.lower(), "with Retry-After")
    s4.close()
    streams[0][0].close()
    c.ok(wait_for(lambda: (health(d.port) or {}).get("event_subscribers") == 2),
         "a stream whose client left is dropped at the next heartbeat")
    s5, head = stream(d.port)
    c.ok(b" 200 " in head.split(b"\r\n")[0], "then a new stream is served")
    s5.close()
    for s, _ in streams[1:]:
        s.close()
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")

    # ---- a request trickled in is cut at its deadline ----
    d.start("--request-timeout", "2")
    s = socket.create_connection(("127.0.0.1", d.port), timeout=ipsd_http.DEADLINE_S)
    s.sendall(b"GET /api/health HTTP/1.1\r\nHost: x\r\nX-Trickle: ")
    cut, t0 = False, time.monotonic()
    # one byte every 0.2 s, for up to 60 s: never idle, never finished
    while time.monotonic() - t0 < 60 and not cut:
        try:
            s.sendall(b"a")
            s.settimeout(0.2)
            cut = s.recv(4096) == b""
        except socket.timeout:
            pass
        except OSError:
            cut = True
    s.close()
    c.ok(cut, "a header trickled a byte every 0.2 s is cut (after %.1f s)" % (time.monotonic() - t0))
    h = health(d.port)
    c.ok(h is not None and h["connections_timed_out"] >= 1,
         "health counts it: %r" % (h and h["connections_timed_out"]))
    c.eq(d.get("/api/health").status, 200, "a normal client is served meanwhile")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
