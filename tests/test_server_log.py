#!/usr/bin/env python3
"""test_server_log.py IPSD IPS: ipsd's log says what matters and nothing else. Dashboard tabs
that close while their event stream is open (the client resets the connection) leave no
libmicrohttpd "Failed to send ..." lines (issue 11: the log of scripts/run.sh filled with them),
and every line ipsd or libmicrohttpd writes carries the "ipsd:" prefix."""
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
    c.eq([l for l in log if not l.startswith("ipsd")], [], "every log line has ipsd's prefix")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
