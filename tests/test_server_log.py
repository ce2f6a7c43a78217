#!/usr/bin/env python3
"""test_server_log.py IPSD IPS: ipsd's log says what matters and nothing else. Dashboard tabs
that close while their event stream is open (the client resets the connection) leave no
libmicrohttpd "Failed to send ..." lines (issue 11: the log of scripts/run.sh filled with them),
and every line ipsd or libmicrohttpd writes carries the "ipsd:" prefix (but the request log's,
which have their own format and record the four streams as aborted)."""
import re
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


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
