#!/usr/bin/env python3
"""test_server_log.py IPSD IPS: ipsd's log says what matters and nothing else. Dashboard tabs
that close while their event stream is open (the client resets the connection) leave no
libmicrohttpd "Failed to send ..." lines (the log of scripts/run.sh filled with them),
and every line ipsd or libmicrohttpd writes carries the "ipsd:" prefix (but the request log's,
which have their own format and record the four streams as aborted). Log rotation
(logrotate's usual contract, docs/operations.md): after the log file is renamed, SIGHUP makes
ipsd reopen --access-log FILE, so the next request's line lands in a new file of that name; no
sleep: the test polls (bounded) for a request's line in the new file."""
import os
import re
import signal
import socket
import struct
import sys

import ipsd_http
from ipsd_http import EventStream, Ipsd


def test(c, t, argv, daemons):
    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start()
    for k in range(4):
        s = EventStream(d.port)
        c.ok(s.ready, "event stream %d subscribed" % k)
        # a closed tab: the browser drops the connection (RST: linger 0), mid-stream
        s.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        s.close()
    # a job's events go to every subscriber still listed, the closed ones included
    sensor = d.post("/api/sensors", {"model": "LOG", "serial": "1"}).json()["id"]
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 10, "row": 10},
                              "raster": {"area_px": 1, "step_um": 2, "sub_px": 3, "frames": 1}})
    c.status(r, 202, "a small scan")
    c.ok(d.wait_job(r.json()["job"]["id"], "done"), "scan done")
    c.eq(d.get("/api/health").status, 200, "ipsd still answers")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")
    log = d.log_text().splitlines()
    c.eq([l for l in log if "Failed to send" in l], [], "no reports of clients that went away")
    # the request log (docs/server.md) has its own format: time, client, method, path, status, ...
    access = re.compile(r"^\d{4}-\d\d-\d\dT[\d:.]+Z \S+ [A-Z]+ /\S* \d{3} ")
    c.eq([l for l in log if not l.startswith("ipsd") and not access.match(l)], [],
         "every other log line has ipsd's prefix")
    c.eq(len([l for l in log if access.match(l) and " GET /api/events 200 " in l and
              l.endswith(" aborted")]), 4,
         "the request log has the four streams, ended by their clients")

    rotate(c, t, argv, daemons)


def rotate(c, t, argv, daemons):
    d = Ipsd(argv[1], t)
    daemons.append(d)
    path = os.path.join(t, "access.log")
    d.start("--access-log", path)
    c.status(d.get("/api/health"), 200, "a request before the rotation")
    line = re.compile(r" GET /api/health 200 ")

    def lines(p):
        try:
            with open(p) as f:
                return [l for l in f.read().splitlines() if line.search(l)]
        except FileNotFoundError:
            return []
    c.ok(ipsd_http.wait_for(lambda: lines(path)), "its line is in the log")
    os.rename(path, path + ".1")  # what logrotate does first (without copytruncate)
    d.proc.send_signal(signal.SIGHUP)

    def rotated():  # SIGHUP is taken by ipsd's main thread: poll, each try a new request
        if d.proc.poll() is not None or d.get("/api/health").status != 200:
            return False
        return lines(path)
    c.ok(ipsd_http.wait_for(rotated), "after SIGHUP a request's line is in a new file")
    c.ok(d.proc.poll() is None, "ipsd still runs after SIGHUP")
    c.eq(len(lines(path + ".1")) >= 1, True, "the renamed file kept the earlier lines")
    c.ok(ipsd_http.wait_for(lambda: "ipsd: SIGHUP: reopened the request log" in d.log_text()),
         "the log says it reopened")
    c.eq(os.stat(path).st_mode & 0o777, 0o640, "the new file is created 0640 like the first")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
