#!/usr/bin/env python3
"""test_server_promote.py IPSD IPS: the lab database changes only on purpose (docs/api.md,
"Calibrations"). Through a real ipsd and its SQLite file (read by Python's sqlite3 module):

- the automatic fit of a finished scan becomes its pixel's calibration (by "ipsd", reason
  "automatic fit of scan N"), and not before it is stored (held at the fit.step failpoint);
- a re-fit of that pixel without "promote" is stored as a fit and leaves the current calibration
  as it was; with "promote": true (by, reason) it replaces it, and the history shows both with
  their provenance;
- POST /api/fits/{id}/promote makes a stored fit's map the calibration (201, Location), also an
  older fit's again; it refuses an unknown fit (404), a fit without a map (409 no_data), a fit
  that already is the calibration (409 conflict) and bad bodies (400 / 422 naming the field),
  changing nothing stored;
- "map": "shrunk" stores the result's shrunk map as the calibration (bad values 422 / 400
  naming map, changing nothing);
- "map": "kriged" stores the result's kriged map (fit/krige.h) on its fine grid: the calibration's
  r is that grid, its S the result's kriged_map.S, its map word "kriged" (schema 8), and its FITS
  file samples that grid; promoted again it is the same map;
- by default (and with --calibration-map kriged) the automatic fit of a scan and a re-fit without
  "map" store the kriged map, the fit document's stored_map and the fit's calibration say so, and
  "map": "recommended" keeps the paper's recommended map (an unknown word: exit status 2 naming
  the option); the parts before run with --calibration-map recommended;
- an upload with a target pixel still becomes the calibration by default, unless
  "promote": false;
- where no kriged map can be made (an upload of 2 points), the calibration is the recommended map
  and its map_note (schema 9) is the fit document's stored_map.why, one sentence naming the
  cause."""
import struct
import subprocess
import sys

import ipsd_http
from ipsd_http import Db, Ipsd

POI = (50, 60)


def map_of(fit):
    """The recommended map of a fit's result document (the `ips fit` JSON): (r, S)."""
    res = fit["result"]
    best = [f for f in res["fits"] if f["r"] == res["recommended_r"]][0]
    return best["r"], best["S"]


def test(c, t, argv, daemons):
    d = Ipsd(argv[1], t)
    daemons.append(d)
    # the automatic fit (the first fit to run) is held at its first step
    d.start("--calibration-map", "recommended", failpoints="fit.step=hold@1")
    db = Db(d.db)
    sensor = d.post("/api/sensors", {"model": "IMX-P", "serial": "promote-1", "n_cols": 128,
                                     "n_rows": 96}).json()["id"]
    pix = "/api/sensors/%d/pixels/%d/%d" % (sensor, POI[0], POI[1])
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": POI[0], "row": POI[1]},
                              "raster": {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2},
                              "seed": 11})
    c.status(r, 202, "submit scan")
    scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_job(job, "done"), "scan done")
    jobs = d.get("/api/jobs?kind=fit&scan=%d" % scan).json()["items"]
    c.eq(len(jobs), 1, "the scan queued its automatic fit")
    auto_job = jobs[0]["id"] if jobs else 0
    c.eq((jobs[0]["params"].get("promote"), jobs[0]["params"].get("by")) if jobs else None,
         (True, "ipsd"), "the automatic fit's job asks to promote, by ipsd")

    # ---- the automatic fit: no calibration until it is stored, then current ----
    c.ok(d.wait_held("fit.step", auto_job), "automatic fit held at its first step")
    c.error(d.get(pix + "/calibration"), 404, "", "no calibration while the fit runs")
    c.eq(db.val("SELECT count(*) FROM calibrations"), 0, "database: no calibration yet")
    d.release("fit.step", auto_job)
    j = d.wait_job(auto_job, "done")
    c.ok(j, "automatic fit done")
    fit1 = j["fit_id"] if j else 0
    cal1 = d.get(pix + "/calibration").json()
    c.eq((cal1.get("fit_id"), cal1.get("by"), cal1.get("reason"), cal1.get("supersedes"),
          cal1.get("current")),
         (fit1, "ipsd", "automatic fit of scan %d" % scan, None, True),
         "the automatic fit is the current calibration, with its provenance")
    f1 = d.get("/api/fits/%d" % fit1).json()
    c.eq(f1["calibration"], {"sensor_id": sensor, "pixel": {"col": POI[0], "row": POI[1]},
                             "r": map_of(f1)[0], "current": True,
                             "current_calibration_id": cal1["id"], "map": "recommended"},
         "the automatic fit's JSON: its map is the current calibration")
    sh1 = f1.get("result", {}).get("shrunk_map")
    c.eq((cal1.get("map"), cal1.get("S_res")),
         ("recommended", sh1["S_res"] if sh1 and sh1["r"] == cal1.get("r") else None),
         "the automatic calibration: the recommended map, with the resolution error of its r")

    # ---- a re-fit without promote: stored as a fit, the calibration unchanged ----
    r = d.post("/api/scans/%d/fits" % scan, {"r_max": 4, "sigma": "shot+read"})
    c.status(r, 202, "re-fit without promote")
    j = d.wait_job(r.json()["job"]["id"], "done")
    c.ok(j, "re-fit done")
    fit2 = j["fit_id"] if j else 0
    c.eq(j["params"]["promote"] if j else None, False, "the re-fit's job: promote false")
    cur = d.get(pix + "/calibration").json()
    c.eq((cur["id"], cur["fit_id"]), (cal1["id"], fit1), "API: the calibration is unchanged")
    c.eq(db.all("SELECT id, fit_id FROM calibrations"), [(cal1["id"], fit1)],
         "database: one calibration, the automatic fit's")
    f2 = d.get("/api/fits/%d" % fit2).json()
    c.eq((f2["calibration"]["current"], f2["calibration"]["current_calibration_id"]),
         (False, cal1["id"]), "the re-fit's JSON: not the calibration, which is the first")
    c.eq(db.val("SELECT count(*) FROM fit_maps WHERE fit_id = ?", fit2), 1,
         "database: the re-fit's map is kept with it")

    # ---- a re-fit with promote: replaces the calibration, with by and reason ----
    r = d.post("/api/scans/%d/fits" % scan, {"r_max": 3, "promote": True, "by": "alice",
                                              "reason": "r <= 3 is what the lab uses"})
    c.status(r, 202, "re-fit with promote")
    j = d.wait_job(r.json()["job"]["id"], "done")
    c.ok(j, "promoted re-fit done")
    fit3 = j["fit_id"] if j else 0
    cal3 = d.get(pix + "/calibration").json()
    f3 = d.get("/api/fits/%d" % fit3).json()
    c.eq((cal3["fit_id"], cal3["supersedes"], cal3["by"], cal3["reason"]),
         (fit3, cal1["id"], "alice", "r <= 3 is what the lab uses"),
         "the promoted re-fit is the calibration, superseding the automatic one")
    c.eq((cal3["r"], cal3["S"]), map_of(f3), "its map is the re-fit's recommended map")
    rr, blob = db.one("SELECT r, s FROM calibrations WHERE superseded_by IS NULL")
    c.eq(list(struct.unpack("<%dd" % (rr * rr), blob)), map_of(f3)[1],
         "database: the current map is the re-fit's (little-endian float64)")
    c.eq(db.all("SELECT id, fit_id, supersedes, superseded_by, changed_by FROM calibrations "
                "ORDER BY id"),
         [(cal1["id"], fit1, None, cal3["id"], "ipsd"),
          (cal3["id"], fit3, cal1["id"], None, "alice")],
         "database: both rows, linked both ways, with who made them current")
    h = d.get(pix + "/history").json()["items"]
    c.eq([(x["id"], x["current"], x["supersedes"], x["by"]) for x in h],
         [(cal3["id"], True, cal1["id"], "alice"), (cal1["id"], False, None, "ipsd")],
         "history: both maps, newest first, with their provenance")
    c.ok(h[1]["superseded_by"] == cal3["id"] and h[1]["created_ms"] <= h[0]["created_ms"],
         "history: the old map superseded by the new one, when")

    # ---- the promote endpoint: refusals change nothing ----
    before = db.all("SELECT id, superseded_by FROM calibrations ORDER BY id")
    c.error(d.post("/api/fits/999/promote", {}), 404, "", "promote an unknown fit")
    c.error(d.post("/api/fits/%d/promote" % fit3, {}), 409, "", "promote the current fit")
    c.eq(d.post("/api/fits/%d/promote" % fit3, {}).json()["error"]["code"], "conflict",
         "already current: code conflict")
    pixel_file = d.get("/api/scans/%d/pixels/0/0" % scan).json()
    r = d.post("/api/fits", {"scan": pixel_file, "r_max": 2})
    j = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
    c.ok(j, "upload without a target pixel fitted")
    fit4 = j["fit_id"] if j else 0
    c.eq(d.get("/api/fits/%d" % fit4).json()["calibration"], None,
         "an upload without a target offers no calibration")
    r = d.post("/api/fits/%d/promote" % fit4, {"reason": "x"})
    c.error(r, 409, "", "promote a fit without a map")
    c.eq(r.json()["error"]["code"], "no_data", "no map: code no_data")
    c.error(d.post("/api/fits/%d/promote" % fit2, {"reason": ""}), 422, "reason", "empty reason")
    c.error(d.post("/api/fits/%d/promote" % fit2, {"by": 5}), 400, "by", "by not a string")
    c.error(d.post("/api/fits/%d/promote" % fit2, {"by": "x" * 65}), 422, "by", "by too long")
    c.error(d.post("/api/fits/%d/promote" % fit2, {"who": "x"}), 422, "who", "unknown member")
    c.error(d.post("/api/fits/%d/promote" % fit2, "{}", {"Content-Type": "text/plain"}), 415, "",
            "promote body not JSON")
    c.error(d.post("/api/fits", {"scan": pixel_file, "promote": True}), 422, "sensor_id",
            "an upload asked to promote without a target pixel")
    c.error(d.post("/api/scans/%d/fits" % scan, {"promote": "yes"}), 400, "promote",
            "promote not a boolean")
    c.eq(db.all("SELECT id, superseded_by FROM calibrations ORDER BY id"), before,
         "the refused requests changed no calibration")

    # ---- the promote endpoint: the stored re-fit, then the automatic fit again ----
    r = d.post("/api/fits/%d/promote" % fit2, {"reason": "shot+read after all"})
    c.status(r, 201, "promote the stored re-fit")
    cal2 = r.json()
    c.eq(r.headers.get("Location"), "/api/calibrations/%d" % cal2.get("id", 0), "Location")
    c.eq((cal2["fit_id"], cal2["supersedes"], cal2["by"], cal2["reason"], cal2["current"],
          cal2["noise_model"]),
         (fit2, cal3["id"], "api", "shot+read after all", True, "shot+read"),
         "promoted: the re-fit's map, superseding the previous, by the default name")
    c.eq((cal2["r"], cal2["S"]), map_of(f2), "the promoted map is the re-fit's recommended map")
    c.eq(d.get(pix + "/calibration").json()["id"], cal2["id"], "API: the promoted map is current")
    r = d.post("/api/fits/%d/promote" % fit1, {"by": "bob"})
    c.status(r, 201, "promote the automatic fit again")
    back = r.json()
    c.eq((back["fit_id"], back["supersedes"], back["by"], back["reason"], back["S"]),
         (fit1, cal2["id"], "bob", "fit %d promoted" % fit1, cal1["S"]),
         "back to the automatic fit's map, with the default reason")
    c.eq(db.val("SELECT count(*) FROM calibrations WHERE superseded_by IS NULL"), 1,
         "database: one current calibration of the pixel")
    c.eq(db.all("SELECT fit_id, changed_by FROM calibrations ORDER BY id"),
         [(fit1, "ipsd"), (fit3, "alice"), (fit2, "api"), (fit1, "bob")],
         "database: the four changes in order, with who made them")
    h = d.get(pix + "/history").json()["items"]
    c.ok(len(h) == 4 and all(h[k]["supersedes"] == h[k + 1]["id"] for k in range(3)),
         "history: a chain of four, each naming the one it superseded")
    c.eq(d.get("/api/fits/%d" % fit2).json()["calibration"]["current"], False,
         "the re-fit is no longer the calibration")

    # ---- "map": "shrunk": the result's shrunk map (fit/shrink.h) becomes the calibration ----
    before = db.all("SELECT id, superseded_by FROM calibrations ORDER BY id")
    c.error(d.post("/api/scans/%d/fits" % scan, {"map": "smooth"}), 422, "map",
            "map neither recommended nor shrunk")
    c.error(d.post("/api/scans/%d/fits" % scan, {"map": 3}), 400, "map", "map not a string")
    c.eq(db.all("SELECT id, superseded_by FROM calibrations ORDER BY id"), before,
         "the refused map requests changed no calibration")
    r = d.post("/api/scans/%d/fits" % scan, {"r_max": 6, "map": "shrunk", "promote": True,
                                              "reason": "the shrunk map"})
    c.status(r, 202, "re-fit storing the shrunk map")
    j = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
    c.ok(j, "shrunk re-fit done")
    c.eq(j["params"].get("map") if j else None, "shrunk", "the job's params record map shrunk")
    f5 = d.get("/api/fits/%d" % (j["fit_id"] if j else 0)).json()
    sh = f5.get("result", {}).get("shrunk_map")
    c.ok(sh is not None and sh["r"] == f5["result"]["recommended_r"],
         "the result has a shrunk map at the recommended r")
    cal5 = d.get(pix + "/calibration").json()
    c.eq((cal5.get("fit_id"), cal5.get("r"), cal5.get("S")),
         (f5.get("id"), sh and sh["r"], sh and sh["S"]),
         "the calibration is the result's shrunk map")
    c.ok(sh is not None and cal5.get("S") != map_of(f5)[1],
         "and not the recommended r's own map")
    rr, blob = db.one("SELECT r, s FROM calibrations WHERE superseded_by IS NULL AND fit_id = ?",
                      f5.get("id"))
    c.eq(list(struct.unpack("<%dd" % (rr * rr), blob)), sh and sh["S"],
         "database: the current map is the shrunk one")
    c.eq(cal5.get("S_res"), sh and sh["S_res"],
         "the calibration keeps the map's resolution error S_res (the result's)")
    c.ok(sh is not None and len(sh["S_res"]) == sh["r"] ** 2 and
         all(v >= 0 for v in sh["S_res"]) and any(v > 0 for v in sh["S_res"]),
         "S_res: r*r non-negative values, not all zero on the paper-like pixel")
    c.eq((cal5.get("map"), db.val("SELECT map FROM calibrations WHERE superseded_by IS NULL"),
          db.val("SELECT map FROM fit_maps WHERE fit_id = ?", f5.get("id"))),
         ("shrunk", "shrunk", "shrunk"), "the calibration says it holds the shrunk map (schema 7)")
    c.eq([x.get("map") for x in d.get(pix + "/history").json()["items"]],
         ["shrunk", "recommended", "recommended", "recommended", "recommended"],
         "history: the shrunk map, and the four recommended maps before it")
    r = d.post("/api/fits/%d/promote" % fit1, {"reason": "the automatic map again"})
    c.eq((r.status, r.json().get("map")), (201, "recommended"),
         "promoting the automatic fit again: a recommended map")
    r = d.post("/api/fits/%d/promote" % f5.get("id", 0), {"reason": "shrunk again"})
    c.eq((r.status, r.json().get("map"), r.json().get("S")), (201, "shrunk", sh and sh["S"]),
         "promoting the shrunk fit again: its shrunk map, named so")

    # ---- "map": "kriged": the result's kriged map, on its fine grid, becomes the calibration ----
    r = d.post("/api/scans/%d/fits" % scan, {"r_max": 6, "map": "kriged", "promote": True,
                                              "reason": "the kriged map"})
    c.status(r, 202, "re-fit storing the kriged map")
    j = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
    c.eq((j["params"].get("map"), j["params"].get("krige")) if j else None, ("kriged", True),
         "the job's params record map kriged (which runs krige)")
    f6 = d.get("/api/fits/%d" % (j["fit_id"] if j else 0)).json()
    km = f6.get("result", {}).get("kriged_map", {})
    rec = f6.get("result", {}).get("recommended_r")
    # fit/krige.h: the grid is the smallest multiple of the recommended r with >= 24 cells a side
    want_grid = rec * -(-24 // rec) if rec else None
    c.eq((km.get("r"), km.get("grid")), (rec, want_grid),
         "the result's kriged map: the recommended r's prior on the smallest multiple >= 24")
    cal6 = d.get(pix + "/calibration").json()
    c.eq((cal6.get("fit_id"), cal6.get("map"), cal6.get("r"), cal6.get("S"), cal6.get("S_err")),
         (f6.get("id"), "kriged", km.get("grid"), km.get("S"), km.get("S_err")),
         "the calibration is the result's kriged map on its grid, named kriged")
    g = km.get("grid") or 1
    c.ok(len(cal6.get("S", [])) == g * g and abs(sum(cal6.get("S", [0])) / (g * g) - 1) < 1e-9,
         "its S: grid^2 values of mean 1")
    c.eq(cal6.get("S_res"), None, "a kriged map has no separate resolution error")
    c.eq((db.val("SELECT map FROM calibrations WHERE superseded_by IS NULL"),
          db.val("SELECT r FROM fit_maps WHERE fit_id = ?", f6.get("id"))), ("kriged", g),
         "database: the current calibration and the fit's map are the kriged grid (schema 8)")
    c.eq(cal6.get("I0"), [f for f in f6["result"]["fits"] if f["r"] == rec][0]["I0"] if rec
         else None, "I0: the recommended r's fit's")
    fits_file = d.get("/api/calibrations/%d/map.fits" % cal6.get("id", 0))
    c.ok(fits_file.status == 200 and b"IPSMAP  = 'kriged" in fits_file.body and
         ("OVERSAMP= %20d" % g).encode() in fits_file.body,
         "its FITS file: IPSMAP kriged, OVERSAMP the grid (%d)" % g)
    r = d.post("/api/fits/%d/promote" % fit1, {"reason": "the automatic map again"})
    c.status(r, 201, "the automatic fit's map promoted again")
    r = d.post("/api/fits/%d/promote" % f6.get("id", 0), {"reason": "kriged again"})
    c.eq((r.status, r.json().get("map"), r.json().get("r"), r.json().get("S")),
         (201, "kriged", g, km.get("S")), "promoting the kriged fit again: its kriged map")

    # ---- uploads with a target pixel: promoted by default, unless promote is false ----
    up = {"scan": pixel_file, "sensor_id": sensor, "pixel": {"col": 10, "row": 11}, "r_max": 2}
    r = d.post("/api/fits", dict(up, promote=False))
    j = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
    c.ok(j, "upload with promote false fitted")
    c.error(d.get("/api/sensors/%d/pixels/10/11/calibration" % sensor), 404, "",
            "an upload with promote false stores no calibration")
    r = d.post("/api/fits", up)
    j = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
    c.ok(j, "upload with a target fitted")
    cal = d.get("/api/sensors/%d/pixels/10/11/calibration" % sensor).json()
    c.eq((cal.get("fit_id"), cal.get("by"), cal.get("reason")),
         (j["fit_id"] if j else None, "api", "fit of an uploaded scan file"),
         "an upload with a target becomes the calibration, as before")
    c.eq(cal.get("map_note"), None, "a calibration that is the map its fit asked for: no map_note")

    # ---- no kriged map can be made (2 points): the recommended map, and the calibration says why
    few = dict(pixel_file)
    for k in ("x_um", "y_um", "signal_dn"):
        few[k] = pixel_file[k][40:42]
    r = d.post("/api/fits", {"scan": few, "sensor_id": sensor, "pixel": {"col": 12, "row": 11},
                             "map": "kriged"})
    j = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
    c.ok(j, "a 2-point upload asking for the kriged map fitted")
    fw = d.get("/api/fits/%d" % (j["fit_id"] if j else 0)).json()
    why = (fw.get("result", {}).get("stored_map") or {}).get("why", "")
    cal = d.get("/api/sensors/%d/pixels/12/11/calibration" % sensor).json()
    c.eq((cal.get("map"), cal.get("r"), fw.get("result", {}).get("recommended_r")),
         ("recommended", 1, 1), "no kriged map from 2 points: the calibration is the r = 1 map")
    c.ok("No kriged map could be made" in why and "at least 3 usable points" in why and
         why.endswith("recommended r = 1 map.") and "\n" not in why,
         "the fit document's stored_map says why in one sentence: %r" % why)
    c.eq(cal.get("map_note"), why, "the calibration keeps that sentence as its map_note")
    c.eq(db.all("SELECT map_note FROM calibrations WHERE id = ?", cal.get("id", 0)), [(why,)],
         "database: calibrations.map_note (schema 9)")
    r = d.post("/api/fits/%d/promote" % (j["fit_id"] if j else 0), {"reason": "again"})
    c.eq(r.status, 409, "promoting the current fit again: 409, nothing written")
    r = d.post("/api/fits/%d/promote" % fit1, {"reason": "back to the automatic map"})
    c.eq((r.status, r.json().get("map_note")), (201, None),
         "promoting a map made as its fit asked: no map_note")

    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")

    # ---- by default the automatic fit stores the kriged map ----
    bad = subprocess.run([argv[1], "--calibration-map", "smooth"], capture_output=True,
                         text=True, timeout=60)
    c.ok(bad.returncode == 2 and "--calibration-map" in bad.stderr and
         len(bad.stderr.strip().splitlines()) == 1,
         "--calibration-map smooth: exit status 2, one line naming the option")
    d.start()
    poi2 = (POI[0] + 10, POI[1])
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": poi2[0], "row": poi2[1]},
                              "raster": {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2},
                              "seed": 12})
    c.status(r, 202, "submit a scan to the kriging ipsd")
    scan2 = r.json()["scan"]["id"] if r.status == 202 else 0
    c.ok(r.status == 202 and d.wait_job(r.json()["job"]["id"], "done"), "scan done")
    jobs = d.get("/api/jobs?kind=fit&scan=%d" % scan2).json()["items"]
    j = d.wait_job(jobs[0]["id"], "done") if jobs else None
    c.eq((j["params"].get("map"), j["params"].get("krige"), j["params"].get("by")) if j else None,
         ("kriged", True, "ipsd"), "the automatic fit's params: map kriged, by ipsd")
    fa = d.get("/api/fits/%d" % (j["fit_id"] if j else 0)).json()
    ka = fa.get("result", {}).get("kriged_map", {})
    cal = d.get("/api/sensors/%d/pixels/%d/%d/calibration" % (sensor, poi2[0], poi2[1])).json()
    c.eq((cal.get("map"), cal.get("r"), cal.get("S"), cal.get("by")),
         ("kriged", ka.get("grid"), ka.get("S"), "ipsd"),
         "the automatic calibration is the kriged map on its grid")
    c.ok(isinstance(ka.get("grid"), int) and ka["grid"] >= 24, "its grid has >= 24 cells a side")
    c.eq(fa.get("result", {}).get("stored_map"), {"map": "kriged", "r": ka.get("grid")},
         "the fit document's stored_map: kriged, on its grid")
    c.eq((fa.get("calibration") or {}).get("map"), "kriged", "the fit's calibration: map kriged")
    # a re-fit without "map" stores the kriged map; "map": "recommended" the paper's map
    for body, want in (({"r_max": 5, "promote": True}, "kriged"),
                       ({"r_max": 5, "promote": True, "map": "recommended"}, "recommended")):
        r = d.post("/api/scans/%d/fits" % scan2, body)
        j = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
        fr = d.get("/api/fits/%d" % (j["fit_id"] if j else 0)).json()
        res = fr.get("result", {})
        if want == "kriged":
            grid = (res.get("kriged_map") or {}).get("grid")
        else:
            grid = res.get("recommended_r")
        cal = d.get("/api/sensors/%d/pixels/%d/%d/calibration" % (sensor, poi2[0], poi2[1])).json()
        c.eq((j["params"].get("map") if j else None, cal.get("fit_id"), cal.get("map"),
              cal.get("r"), res.get("stored_map")),
             (want, j and j["fit_id"], want, grid, {"map": want, "r": grid}),
             "a re-fit with %s stores the %s map" % (body, want))
    db.close()
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
