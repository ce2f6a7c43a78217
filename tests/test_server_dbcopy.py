#!/usr/bin/env python3
"""test_server_dbcopy.py IPSD IPS URI-FILE: a bench's SQLite database joins the lab's PostgreSQL
database (ipsd --db-copy FROM TO) without losing its history, and a second copy copies nothing
twice. A bench ipsd on SQLite scans a pixel (its automatic fit makes the first calibration) and
stores a second map of it; the lab database (a fresh schema of the suite's server) already knows
the sensor. After the copy, Python's sqlite3 module (the source) and psql (the target) agree on
every scan, every frame's bytes, every fit and fit map, the calibration history of the pixel and
the scan job's bench; an ipsd on the lab database serves the copied map as the bench served it;
a second run copies nothing; bad input exits 2 with one line."""
import json
import os
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd

RASTER = {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}


def test(c, t, argv, daemons):
    try:
        with open(argv[3]) as f:
            base = f.read().strip()
    except OSError:
        print("no PostgreSQL server for the tests (%s): skipped" % argv[3])
        raise SystemExit(77)
    ipsd = argv[1]
    # ---- the bench, on SQLite: a scan, its automatic fit, a second map of the pixel ----
    bench = Ipsd(ipsd, t)
    bench.db = os.path.join(t, "bench.db")
    daemons.append(bench)
    bench.start()
    sensor = bench.post("/api/sensors", {"model": "IMX-COPY", "serial": "7", "pitch_um": 6}).json()["id"]
    r = bench.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 12, "row": 14},
                                  "raster": RASTER, "seed": 3})
    c.status(r, 202, "a scan on the bench")
    scan, scan_job = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(bench.wait_job(scan_job, "done"), "the scan is done")
    auto = bench.get("/api/jobs?kind=fit&scan=%d" % scan).json()["items"]
    c.ok(auto and bench.wait_job(auto[0]["id"], "done"), "its automatic fit is done")
    path = os.path.join(t, "pixel.json")
    subprocess.run([argv[2], "simulate", "--scene", "paperlike", "--seed", "5", "-o", path],
                   check=True, stdout=subprocess.DEVNULL)
    with open(path) as f:
        scan_file = json.load(f)
    r = bench.post("/api/fits", {"scan": scan_file, "sensor_id": sensor,
                                 "pixel": {"col": 12, "row": 14}, "r_max": 3})
    c.ok(r.status == 202 and bench.wait_job(r.json()["job"]["id"], "done"),
         "a second map of the pixel")
    r = bench.post("/api/fits", {"scan": scan_file, "sensor_id": sensor,
                                 "pixel": {"col": 30, "row": 31}, "r_max": 2})
    c.ok(r.status == 202 and bench.wait_job(r.json()["job"]["id"], "done"),
         "a map of another pixel, which the lab will map again later")
    pix = "/api/sensors/%d/pixels/12/14/calibration" % sensor
    served = bench.get(pix).json()
    c.eq(bench.stop_term(), 0, "the bench stops")

    # ---- the lab's database knows the sensor already ----
    ipsd_http._PG_URI_FILE = argv[3]  # a fresh schema of the suite's server for the lab
    lab = Ipsd(ipsd, os.path.join(t, "lab"))
    os.makedirs(lab.tmp)
    daemons.append(lab)
    lab.start("--bench-name", "lab")
    lab_sensor = lab.post("/api/sensors", {"model": "IMX-COPY", "serial": "7",
                                           "pitch_um": 6}).json()["id"]
    lab.post("/api/sensors", {"model": "OTHER", "serial": "1"})
    r = lab.post("/api/fits", {"scan": scan_file, "sensor_id": lab_sensor,
                               "pixel": {"col": 30, "row": 31}, "r_max": 1})
    c.ok(r.status == 202 and lab.wait_job(r.json()["job"]["id"], "done"),
         "the lab maps that pixel, later than the bench")
    lab_map = Db(lab.db).val("SELECT id FROM calibrations WHERE pixel_col = 30")
    c.eq(lab.stop_term(), 0, "the lab's ipsd stops")
    before = Db(lab.db)
    lab_fits, lab_jobs, lab_cal = (before.val("SELECT count(*) FROM fits"),
                                   before.val("SELECT max(id) FROM jobs"),
                                   before.val("SELECT count(*) FROM calibrations"))

    # ---- the copy ----
    def copy(*extra):
        return subprocess.run([ipsd, "--db-copy", bench.db, *extra], capture_output=True,
                              text=True, timeout=300)
    r = copy(lab.db, "--bench-name", "bench-7")
    c.eq(r.returncode, 0, "the copy: exit 0 (%s)" % r.stderr.strip())
    print(r.stdout.strip())
    src = Db(bench.db)
    n_frames = src.val("SELECT count(*) FROM frames")
    n_fits = src.val("SELECT count(*) FROM fits")
    n_cal = src.val("SELECT count(*) FROM calibrations WHERE pixel_col = 12")
    c.ok("0 sensor(s) (1 more found there), 1 scan(s) (%d points)" % n_frames in r.stdout,
         "it says what it copied")
    dst = Db(lab.db)
    c.eq(dst.val("SELECT count(*) FROM sensors"), 2, "the sensor known to both is one row")
    c.eq(dst.all("SELECT sensor_id, poi_col, poi_row, state, points_done FROM scans"),
         [(lab_sensor, 12, 14, "done", n_frames)], "the scan, on the lab's sensor id")
    got = dst.all("SELECT point_index, stage_x_um, stage_y_um, mean, raw FROM frames "
                  "ORDER BY point_index")
    want = src.all("SELECT point_index, stage_x_um, stage_y_um, mean, raw FROM frames "
                   "ORDER BY point_index")
    c.ok(len(got) == n_frames and got == want, "every frame, byte for byte")
    c.eq(dst.val("SELECT count(*) FROM frame_times"), src.val("SELECT count(*) FROM frame_times"),
         "every frame's times")
    c.eq((dst.val("SELECT count(*) FROM fits"), dst.val("SELECT count(*) FROM fit_maps")),
         (lab_fits + n_fits, lab_fits + src.val("SELECT count(*) FROM fit_maps")),
         "every fit and the map it offers, beside the lab's")
    copied = dst.all("SELECT result FROM fits")
    c.ok(all(x in copied for x in src.all("SELECT result FROM fits")), "the fits' results")
    c.eq(dst.all("SELECT kind, state, bench FROM jobs WHERE id > %d ORDER BY id" % lab_jobs),
         [(k, s, "bench-7" if k != "fit" else None)
          for k, s in src.all("SELECT kind, state FROM jobs ORDER BY id")],
         "every job, the scan's now bench-7's")
    c.eq(dst.val("SELECT count(*) FROM jobs j WHERE fit_id IS NOT NULL AND NOT EXISTS "
                 "(SELECT 1 FROM fits f WHERE f.id = j.fit_id AND f.job_id = j.id)"), 0,
         "each job names its own fit, and the fit its job")
    hist = dst.all("SELECT id, superseded_by, supersedes, hex(s) FROM calibrations "
                   "WHERE pixel_col = 12 AND pixel_row = 14 ORDER BY id")
    shist = src.all("SELECT id, superseded_by, supersedes, hex(s) FROM calibrations "
                    "WHERE pixel_col = 12 AND pixel_row = 14 ORDER BY id")
    c.eq(len(hist), n_cal, "the pixel's whole history")
    c.ok(len(hist) == 2 and hist[0][1] == hist[1][0] and hist[1][1] is None and
         hist[1][2] == hist[0][0], "older superseded by newer, the newer current")
    c.eq([h[3] for h in hist], [h[3] for h in shist], "the maps, byte for byte")

    c.eq(dst.all("SELECT id = %d, superseded_by IS NULL FROM calibrations WHERE pixel_col = 30 "
                 "ORDER BY created_ms, id" % lab_map), [(0, 0), (1, 1)],
         "a pixel mapped by both: the newer map (the lab's) stays current, the bench's older one "
         "is history before it")
    c.eq(dst.val("SELECT supersedes FROM calibrations WHERE id = %d" % lab_map),
         dst.val("SELECT id FROM calibrations WHERE pixel_col = 30 AND id <> %d" % lab_map),
         "and the lab's map says which it supersedes")

    # ---- again: nothing twice ----
    r = copy("--bench-name", "bench-7", lab.db)
    c.eq(r.returncode, 0, "the second copy: exit 0")
    c.ok("0 sensor(s) (0 more found there), 0 scan(s) (0 points), 0 job(s), 0 fit(s), "
         "0 calibration(s), 0 ptc" in r.stdout, "it copies nothing: " + r.stdout.strip())
    n_all = dst.val("SELECT count(*) FROM calibrations")
    c.eq(n_all, lab_cal + src.val("SELECT count(*) FROM calibrations"),
         "every calibration of the bench, beside the lab's")
    c.eq((dst.val("SELECT count(*) FROM frames"), dst.val("SELECT count(*) FROM calibrations")),
         (n_frames, n_all), "the lab's rows are as they were")

    # ---- the lab serves the copied map as the bench did ----
    lab.start("--bench-name", "lab")
    got = lab.get("/api/sensors/%d/pixels/12/14/calibration" % lab_sensor).json()
    c.eq((got.get("S"), got.get("S_err"), got.get("r"), got.get("map")),
         (served["S"], served["S_err"], served["r"], served["map"]),
         "the lab's current map of the pixel is the bench's")
    c.eq(lab.stop_term(), 0, "the lab's ipsd stops")

    # ---- bad input ----
    for args, what in (([os.path.join(t, "no-such.db"), lab.db], "a source that does not exist"),
                       ([bench.db, bench.db], "the same database twice"),
                       ([bench.db], "no target")):
        r = subprocess.run([ipsd, "--db-copy", *args], capture_output=True, text=True, timeout=60)
        c.eq((r.returncode, len(r.stderr.strip().splitlines())), (2, 1),
             "%s: exit 2 and one line (%s)" % (what, r.stderr.strip()))
    c.eq(dst.val("SELECT count(*) FROM calibrations"), n_all, "nothing was written by them")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
