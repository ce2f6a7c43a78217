#!/usr/bin/env python3
"""test_server_points.py IPSD: GET /api/scans/{id}/points/{index} of a point whose frames would
make a reply larger than --max-reply-bytes: refused with 413 naming raw_limit and the frames a
request may ask for, and the raw frames asked for in pages (?raw_offset=&raw_limit=) read back
equal to the stored blobs as Python's sqlite3 reads them (little-endian uint16 frames, float64
mean), page after page, with nothing stored changed."""
import math
import struct
import sys

import ipsd_http
from ipsd_http import Db, Ipsd

SUB, FRAMES, CAP = 63, 64, 1 << 20


def test(c, t, argv, daemons):
    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start("--max-reply-bytes", str(CAP))
    db = Db(d.db)
    r = d.post("/api/sensors", {"model": "IMX-P", "serial": "points-1"})
    c.status(r, 201, "sensor")
    r = d.post("/api/scans", {"sensor_id": r.json()["id"], "poi": {"col": 40, "row": 40},
                              "raster": {"area_px": 1, "step_um": 6, "sub_px": SUB,
                                         "frames": FRAMES}})
    c.status(r, 202, "scan submitted")
    scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_job(job, "done"), "the scan finished")
    m2 = SUB * SUB
    raw_blob, mean_blob = db.one("SELECT raw, mean FROM frames WHERE scan_id = ? AND "
                                 "point_index = 0", scan)
    raw = struct.unpack("<%dH" % (FRAMES * m2), raw_blob)
    mean = struct.unpack("<%dd" % m2, mean_blob)
    before = db.one("SELECT count(*), sum(length(raw)) FROM frames")

    # the whole point: 64 frames of 63 x 63 are ~1.5 MB of JSON, over the 1 MiB cap
    r = d.get("/api/scans/%d/points/0" % scan)
    c.error(r, 413, "raw_limit", "the whole point is refused")
    msg = r.json()["error"]["message"]
    c.ok("--max-reply-bytes" in msg and "raw_offset" in msg, "the message names the flag and "
         "the parameters: %s" % msg)
    # the frames a page may hold, by the bound docs/api.md states: 6 bytes a raw value, 3 a frame,
    # 42 a frame's timestamp and id
    page = int(msg.split("at most ")[1].split(" ")[0])
    want_page = (CAP - 1024 - m2 * 25) // (m2 * 6 + 3 + 42)
    c.eq(page, want_page, "frames a request may ask for")
    c.ok(0 < page < FRAMES, "a page is fewer than the point's frames")

    # page by page: the stored frames, exactly
    got, stamps, ids = [], [], []
    off = 0
    while off < FRAMES:
        r = d.get("/api/scans/%d/points/0?raw_offset=%d&raw_limit=%d" % (scan, off, page))
        if not c.status(r, 200, "page at %d" % off):
            break
        j = r.json()
        c.ok(len(r.body) <= CAP, "page at %d: %d bytes, within the cap" % (off, len(r.body)))
        c.eq((j["frames"], j["sub_px"], j["raw_offset"]), (FRAMES, SUB, off), "page's members")
        c.eq(len(j["raw"]), min(page, FRAMES - off), "page at %d: frames" % off)
        got.extend(v for fr in j["raw"] for v in fr)
        stamps.extend(j.get("timestamps_ns") or [])
        ids.append(j.get("camera_frame_ids", "absent"))
        c.ok(all(a == b or (a is None and math.isnan(b)) for a, b in zip(j["mean"], mean)) and
             len(j["mean"]) == m2, "page at %d: the stored mean frame" % off)
        off += page
    c.ok(tuple(got) == raw, "the pages' raw frames are the stored blob (%d of %d values)"
         % (len(got), len(raw)))
    # each frame's timestamp, page by page (schema 10): the simulated bench's clock runs at least
    # an exposure from one frame's start to the next; it has no frame ids of its own
    exposure_ns = db.val("SELECT exposure_us FROM frames WHERE scan_id = ? AND point_index = 0",
                         scan) * 1000
    c.ok(len(stamps) == FRAMES and all(b - a >= exposure_ns for a, b in zip(stamps, stamps[1:])),
         "timestamps_ns: one a frame, an exposure (%.0f ns) or more apart (%s)"
         % (exposure_ns, stamps[:3]))
    c.eq(set(map(str, ids)), {"None"}, "camera_frame_ids: null, the simulated bench has none")
    # a few frames from the middle, and none
    r = d.get("/api/scans/%d/points/0?raw_offset=7&raw_limit=2" % scan)
    c.status(r, 200, "frames 7 and 8")
    c.ok([v for fr in r.json()["raw"] for v in fr] == list(raw[7 * m2:9 * m2]),
         "frames 7 and 8 are the stored ones")
    r = d.get("/api/scans/%d/points/0?raw_limit=0" % scan)
    c.status(r, 200, "no raw frame")
    c.eq(r.json()["raw"], [], "raw_limit=0: raw is empty")
    # a limit past the end is the frames there are
    r = d.get("/api/scans/%d/points/0?raw_offset=%d&raw_limit=%d" % (scan, FRAMES - 1, page))
    c.status(r, 200, "the last frame")
    c.eq(len(r.json()["raw"]), 1, "the last frame only")
    c.error(d.get("/api/scans/%d/points/0?raw_offset=%d" % (scan, FRAMES + 1)), 422,
            "raw_offset", "an offset past the frames")
    c.error(d.get("/api/scans/%d/points/0?raw_limit=-1" % scan), 422, "raw_limit",
            "a negative limit")
    c.error(d.get("/api/scans/%d/points/9" % scan), 404, "index", "a point outside the raster")
    # the scan file with the whole sub-frame: this one fits, a wider sub-frame's does not
    r = d.get("/api/scans/%d/scanfile" % scan)
    c.status(r, 200, "the scan file of 4 points of 63 x 63")
    c.eq(len(r.json()["subframe"]["signal_dn"]), 4, "its sub-frame's points")
    r = d.post("/api/scans", {"sensor_id": 1, "poi": {"col": 80, "row": 80},
                              "raster": {"area_px": 1, "step_um": 6, "sub_px": 121,
                                         "frames": 1}})
    c.status(r, 202, "a scan of 121 x 121 pixels")
    wide, job = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_job(job, "done"), "the wide scan finished")
    before = db.one("SELECT count(*), sum(length(raw)) FROM frames")
    # 4 x 121² means of up to 25 bytes each: 1.46 MB, over the 1 MiB cap
    r = d.get("/api/scans/%d/scanfile" % wide)
    c.error(r, 413, "", "the wide scan's scan file is refused")
    c.ok("--max-reply-bytes" in r.json()["error"]["message"], "the message names the flag")
    r = d.get("/api/scans/%d/points/3" % wide)
    c.status(r, 200, "its point of one frame is answered whole")
    c.eq(len(r.json()["raw"]), 1, "one raw frame")
    c.eq(db.one("SELECT count(*), sum(length(raw)) FROM frames"), before, "nothing stored changed")
    db.close()
    c.eq(d.stop_term(), 0, "ipsd stops cleanly")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
