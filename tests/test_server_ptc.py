#!/usr/bin/env python3
"""test_server_ptc.py IPSD IPS: photon transfer on the bench through the API.

- POST /api/sensors/{id}/ptc queues a measurement (202, the job, Location); the scan worker runs it
  (kind "ptc"), publishing progress events; GET /api/sensors/{id}/ptc gives the current
  measurement and the history, GET /api/ptc/{id} one. The measured gain and read noise are within
  2 % of the simulated sensor's (the sensor row: the simulator's truth), and equal what
  `ips ptc --sim` measures with the same series, pixels and seed (an independent run of the same
  simulator and analysis).
- Cancel: a job held at its second level (failpoint ptc.level) and cancelled stores nothing.
- Crashes (SIGKILL by the crash failpoint) after the store's transaction (ptc.after_store) and
  before it (ptc.before_store): after a restart each job is done with exactly one measurement.
- Bad requests: 404 (unknown sensor, unknown measurement), 422 (levels out of range, an unknown
  member), 400 (not a JSON object).
- Fits use the measured constants for sigma (eq. 5): a fit of a scan of the sensor records
  noise_source "sensor" before any measurement, "ptc #ID" with the measurement's gain and read
  noise after, "request" when the request gives them; with sigma "shot+read",
  sigma^2 = ((I - B)/G + (R/G)^2) / frames, so a gain four times larger with a read noise twice
  larger divides every sigma^2 by exactly 4 and multiplies each r's chi2_red by exactly 4 (the
  weighted least-squares solution does not change when all weights scale alike) - whether the
  constants come from the request or from a newer measurement of the sensor."""
import json
import os
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, EventStream, Ipsd

LEVELS, ROI = 20, 128  # 128 x 128 pixels: gain within 0.3 % of the truth, seconds per run
TRUE_GAIN, TRUE_NOISE = 3.153, 5.67  # the sensor created below (the paper's; the simulator's)


def ptc_body():
    return {"levels": LEVELS, "roi_px": ROI, "seed": 1}


def chi2_by_r(fit):
    return {f["r"]: f["chi2_red"] for f in fit["result"]["fits"]}


def test(c, t, argv, daemons):
    ips = argv[2]
    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start(failpoints="ptc.level=hold@2;ptc.after_store=hold@1;ptc.after_store=crash@1")
    db = Db(d.db)
    r = d.post("/api/sensors", {"model": "IMX-PTC", "serial": "ptc-1", "pitch_um": 6,
                                "gain_e_per_dn": TRUE_GAIN, "read_noise_e": TRUE_NOISE})
    c.status(r, 201, "create a sensor")
    sensor = r.json()["id"]

    # ---- bad requests ----
    c.error(d.post("/api/sensors/999/ptc", {}), 404, "", "unknown sensor")
    c.error(d.post("/api/sensors/%d/ptc" % sensor, {"levels": 2}), 422, "levels", "levels < 3")
    # what the bench cannot honour is refused before a job is queued, naming the limit: a
    # region over the simulator's one-capture memo (856 x 856), too few levels for a slope
    jobs = db.val("SELECT count(*) FROM jobs")
    for body, field, word in (({"roi_px": 857}, "roi_px", "2..856"),
                              ({"roi_px": 4096, "levels": 40}, "roi_px", "2..856"),
                              ({"levels": 5}, "levels", "at least 6"),
                              ({"levels": 3, "flat_e": 10000}, "levels", "at least 4")):
        r = d.post("/api/sensors/%d/ptc" % sensor, body)
        c.error(r, 422, field, "%r: refused" % body)
        c.ok(word in r.text, "%r: the limit named (%s)" % (body, r.text[:200]))
    c.eq(db.val("SELECT count(*) FROM jobs"), jobs, "no job queued by the refused requests")
    c.error(d.post("/api/sensors/%d/ptc" % sensor, {"lamp": 1}), 422, "lamp", "unknown member")
    c.error(d.post("/api/sensors/%d/ptc" % sensor, [1]), 400, "", "not an object")
    c.error(d.get("/api/ptc/1"), 404, "", "no measurement yet")
    c.error(d.get("/api/sensors/999/ptc"), 404, "", "history of an unknown sensor")
    r = d.get("/api/sensors/%d/ptc" % sensor)
    c.status(r, 200, "history before any measurement")
    c.eq((r.json()["current"], r.json()["history"]), (None, []), "nothing measured yet")

    # ---- a scan of the sensor, and a fit of it before any measurement: the sensor's constants
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": 30, "row": 30},
                              "raster": {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2}})
    c.status(r, 202, "submit a scan")
    scan, scan_job = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_job(scan_job, "done"), "the scan is done")
    fit_req = {"sigma": "shot+read", "r_max": 3}

    def fit(extra=None):
        body = dict(fit_req, **(extra or {}))
        r = d.post("/api/scans/%d/fits" % scan, body)
        if not c.status(r, 202, "fit request %r" % body):
            return None
        job = d.wait_job(r.json()["job"]["id"], "done")
        if not c.ok(job and job["fit_id"], "the fit job is done with a fit"):
            return None
        r = d.get("/api/fits/%d" % job["fit_id"])
        c.status(r, 200, "get the fit")
        return r.json()

    f_sensor = fit()
    if f_sensor:
        c.eq(f_sensor["result"]["noise_source"], "sensor", "no measurement: the sensor's")
        c.eq(f_sensor["result"]["noise_constants"],
             {"gain_e_per_dn": TRUE_GAIN, "read_noise_e": TRUE_NOISE, "ptc_id": None},
             "no measurement: the sensor row's constants")

    # ---- a measurement cancelled at its second level stores nothing ----
    ev = EventStream(d.port)
    r = d.post("/api/sensors/%d/ptc" % sensor, ptc_body())
    c.status(r, 202, "queue a measurement")
    c.ok(r.headers.get("Location", "").startswith("/api/jobs/"), "Location names the job")
    job1 = r.json()["job"]
    # a free instrument worker may claim the job before the reply reads it back
    c.ok(job1["kind"] == "ptc" and job1["state"] in ("queued", "running"),
         "a ptc job, queued or already claimed: %s/%s" % (job1["kind"], job1["state"]))
    c.eq(job1["params"], {"sensor_id": sensor, "levels": LEVELS, "roi_px": ROI, "flat_e": 0.0,
                          "seed": 1}, "the job's params")
    c.ok(d.wait_held("ptc.level", job1["id"]), "held after its second level")
    c.eq(d.job_state(job1["id"]), "running", "running while held")
    c.status(d.post("/api/jobs/%d/cancel" % job1["id"]), 200, "cancel it")
    c.ok(d.wait_job(job1["id"], "cancelled"), "the measurement is cancelled")
    c.eq(db.val("SELECT count(*) FROM ptc"), 0, "a cancelled measurement stores nothing")

    def level_one():
        # the stream's reader thread gets the event when ipsd's write reaches it, not when the
        # job was held or cancelled: wait for it (a snapshot raced it on a loaded machine)
        return any(e.get("id") == job1["id"] and e.get("phase") == "ptc" and
                   e.get("points_done") == 1 and e.get("points_total") == LEVELS
                   for e in ev.events())
    c.ok(ipsd_http.wait_for(level_one), "a progress event says level 1 of %d" % LEVELS)
    ev.close()

    # ---- a measurement crashed after its store: done once, not run again ----
    r = d.post("/api/sensors/%d/ptc" % sensor, ptc_body())
    c.status(r, 202, "queue a second measurement")
    job2 = r.json()["job"]["id"]
    # held after the store first, crashing when released: the 202 above came before the crash
    c.ok(d.release_when_held("ptc.after_store", job2, ipsd_http.DEADLINE_S * 2),
         "the second measurement is held after its store")
    c.eq(d.wait_exit(), -9, "ipsd crashed at ptc.after_store")
    d.start(failpoints="ptc.before_store=crash@1")
    c.eq(db.one("SELECT state, attempts FROM jobs WHERE id = ?", job2), ("done", 1),
         "after the crash past its store the job is done (claimed once)")
    c.eq(db.all("SELECT job_id FROM ptc"), [(job2,)], "exactly one measurement, the job's")

    r = d.get("/api/sensors/%d/ptc" % sensor)
    c.status(r, 200, "the sensor's photon transfer")
    cur = r.json()["current"]
    if c.ok(cur is not None, "a current measurement"):
        c.eq(cur["job_id"], job2, "the current measurement is the job's")
        c.ok(abs(cur["gain_e_per_dn"] / TRUE_GAIN - 1) < 0.02,
             "gain %.4f within 2 %% of the simulator's %.3f" % (cur["gain_e_per_dn"], TRUE_GAIN))
        c.ok(abs(cur["read_noise_e"] / TRUE_NOISE - 1) < 0.02,
             "read noise %.4f within 2 %% of the simulator's %.2f"
             % (cur["read_noise_e"], TRUE_NOISE))
        c.ok(cur["gain_err_e_per_dn"] > 0, "the gain has an uncertainty")
        c.ok(abs(cur["dark_dn"] - 100) < 0.5,
             "dark level %.3f at the bias, 100 DN" % cur["dark_dn"])
        c.eq(len(cur["result"]["levels"]), LEVELS, "the report has every level")
        # the same series on the same simulator by `ips ptc --sim`: the same numbers
        out = subprocess.run([ips, "ptc", "--sim", "--levels", str(LEVELS), "--roi", str(ROI),
                              "--seed", "1"], capture_output=True, text=True, timeout=300)
        if c.eq(out.returncode, 0, "ips ptc --sim runs"):
            cli = json.loads(out.stdout)
            c.eq((cur["gain_e_per_dn"], cur["read_noise_e"], cur["saturation_dn"]),
                 (cli["gain_e_per_dn"], cli["read_noise_e"], cli["saturation_dn"]),
                 "the job measures what ips ptc --sim measures")
        one = d.get("/api/ptc/%d" % cur["id"])
        c.status(one, 200, "the one measurement by id")
        c.eq(one.json(), cur, "by id: the same as the current one")

    # ---- a fit after the measurement: its gain and read noise ----
    f_ptc = fit()
    if f_ptc and cur:
        c.eq(f_ptc["result"]["noise_source"], "ptc #%d" % cur["id"], "the measurement's")
        c.eq(f_ptc["result"]["noise_constants"],
             {"gain_e_per_dn": cur["gain_e_per_dn"], "read_noise_e": cur["read_noise_e"],
              "ptc_id": cur["id"]}, "the measured constants")
        f_req = fit({"gain_e_per_dn": cur["gain_e_per_dn"], "read_noise_e": cur["read_noise_e"]})
        if f_req:
            c.eq(f_req["result"]["noise_source"], "request", "the request's")
            c.eq(chi2_by_r(f_req), chi2_by_r(f_ptc), "the same constants: the same chi2")
        f_4 = fit({"gain_e_per_dn": 4 * cur["gain_e_per_dn"],
                   "read_noise_e": 2 * cur["read_noise_e"]})
        if f_4:
            a, b = chi2_by_r(f_4), chi2_by_r(f_ptc)
            c.ok(all(abs(a[r] / b[r] - 4) < 1e-9 for r in b),
                 "4 G, 2 R: chi2_red times 4 (%r vs %r)" % (a, b))

    # ---- a measurement crashed before its store: run again, stored once ----
    r = d.post("/api/sensors/%d/ptc" % sensor, ptc_body())
    c.status(r, 202, "queue a third measurement")
    job3 = r.json()["job"]["id"]
    c.eq(d.wait_exit(ipsd_http.DEADLINE_S * 2), -9, "ipsd crashed at ptc.before_store")
    c.eq(db.val("SELECT count(*) FROM ptc WHERE job_id = ?", job3), 0, "nothing stored")
    # a newer measurement of the sensor (as another bench would give): 4 G, 2 R
    if cur:
        db.conn.execute("INSERT INTO ptc (sensor_id, gain_e_per_dn, read_noise_e, result, "
                        "created_ms) VALUES (?, ?, ?, '{}', 1)",
                        (sensor, 4 * cur["gain_e_per_dn"], 2 * cur["read_noise_e"]))
    crafted = db.val("SELECT max(id) FROM ptc")
    d.start()
    f_new = fit()
    if f_new and f_ptc:
        c.eq(f_new["result"]["noise_source"], "ptc #%d" % crafted, "the newest measurement's")
        a, b = chi2_by_r(f_new), chi2_by_r(f_ptc)
        c.ok(all(abs(a[r] / b[r] - 4) < 1e-9 for r in b),
             "a measured gain 4 times larger: chi2_red times 4 (%r vs %r)" % (a, b))
    c.ok(d.wait_job(job3, "done"), "the crashed measurement ran again to its end")
    c.eq(db.val("SELECT count(*) FROM ptc WHERE job_id = ?", job3), 1, "stored once")
    h = d.get("/api/sensors/%d/ptc" % sensor).json()
    c.eq([m["job_id"] for m in h["history"]], [job3, None, job2], "the history, newest first")
    c.eq(h["current"]["job_id"], job3, "the current is the newest")
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
