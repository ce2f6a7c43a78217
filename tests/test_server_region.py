#!/usr/bin/env python3
"""test_server_region.py IPSD IPS: the fit region of POST /api/fits (and of a scan's fits) on a
real ipsd. An uploaded scan file holds a 15 x 15 raster at 0.6 um steps from -1.2 um to 7.2 um
over a 6 um pixel (points inside and outside it); the points each region keeps are counted here
from the file by fit/region.h's rule (strictly inside (0, pitch)^2; within the margin), and the
stored fit document must say the region and fit exactly those points, with the Wiener map the
raster's nodes inside the pixel. Bad regions are refused (400 / 422 naming the field) and store
nothing."""
import json
import math
import os
import subprocess
import sys
import tempfile

import ipsd_http
from ipsd_http import Db, Ipsd

PITCH, STEP, N = 6.0, 0.6, 15
X0 = -1.2
R_SPOT = 1.342


def scan_file():
    """A smooth, positive response: brightest at the pixel's centre, falling off outside."""
    xs, ys, s = [], [], []
    for j in range(N):
        for i in range(N):
            x, y = X0 + i * STEP, X0 + j * STEP
            fx = 1 / (1 + math.exp(-(x - 0.2) / 0.5)) / (1 + math.exp((x - 5.8) / 0.5))
            fy = 1 / (1 + math.exp(-(y - 0.2) / 0.5)) / (1 + math.exp((y - 5.8) / 0.5))
            xs.append(x)
            ys.append(y)
            s.append(100 + 2000 * fx * fy * (1 + 0.05 * math.sin(x + 2 * y)))
    return {"pitch_um": PITCH, "spot_radius_um": R_SPOT, "bias_dn": 100, "gain_e_per_dn": 3.153,
            "read_noise_e": 5.67, "frames": 12, "x_um": xs, "y_um": ys, "signal_dn": s}


def count(scan, margin=None):
    eps = 1e-6 * PITCH
    def keep(v):
        if margin is None:
            return eps < v < PITCH - eps
        return -margin - eps <= v <= PITCH + margin + eps
    return sum(keep(x) and keep(y) for x, y in zip(scan["x_um"], scan["y_um"]))


def test(c, t, argv, daemons):
    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start()
    db = Db(d.db)
    scan = scan_file()
    base = {"scan": scan, "r_min": 1, "r_max": 3, "wiener": True}

    def fits_jobs():
        return db.one("SELECT (SELECT count(*) FROM jobs), (SELECT count(*) FROM fits)")
    before = fits_jobs()
    for extra, status, field in [
            ({"region": "outside"}, 422, "region"),
            ({"region": 3}, 400, "region"),
            ({"region": "margin"}, 422, "margin_um"),
            ({"region": "margin", "margin_um": -1}, 422, "margin_um"),
            ({"region": "margin", "margin_um": "wide"}, 400, "margin_um"),
            ({"region": "inside", "margin_um": 1}, 422, "margin_um"),
            ({"margin_um": 1}, 422, "margin_um"),
            ({"fit_geometry": "yes"}, 400, "fit_geometry"),
            ({"geometry_r": 3}, 422, "geometry_r"),
            ({"fit_geometry": True, "geometry_r": 0}, 422, "geometry_r"),
            ({"geometry_model": "map"}, 422, "geometry_model"),
            ({"fit_geometry": True, "geometry_model": "spline"}, 422, "geometry_model"),
            ({"fit_geometry": True, "geometry_model": 1}, 400, "geometry_model"),
            ({"krige": "yes"}, 400, "krige")]:
        c.error(d.post("/api/fits", dict(base, **extra)), status, field, "upload with %r" % extra)
    c.eq(fits_jobs(), before, "bad regions stored nothing")

    inside_nodes = [X0 + i * STEP for i in range(N) if 6e-6 < X0 + i * STEP < PITCH - 6e-6]
    for extra, margin, name in [({}, None, "inside"), ({"region": "inside"}, None, "inside"),
                                ({"region": "margin", "margin_um": 0.6}, 0.6, "margin"),
                                ({"region": "all"}, 1e9, "all")]:
        r = d.post("/api/fits", dict(base, **extra))
        c.status(r, 202, "upload with %r" % extra)
        if r.status != 202:
            continue
        j = d.wait_job(r.json()["job"]["id"], "done")
        c.ok(j, "fit %r done" % extra)
        if not j:
            continue
        c.eq((j["params"]["region"], j["params"].get("margin_um")),
             (name, margin if name == "margin" else None), "job params record the region")
        res = d.get("/api/fits/%d" % j["fit_id"]).json()["result"]
        want = count(scan, margin)
        c.eq((res["region"], res["margin_um"], res["n_points"], res["n_raster"]),
             (name, margin if name == "margin" else None, want, N * N),
             "stored fit %r: region and points" % extra)
        c.eq(res["fits"][0]["n_used"], want, "the fit used the region's points")
        w = res["wiener"]
        c.eq((w["raster"], w["cropped"], w["nx"], w["ny"], w["region"]),
             ([N, N], True, len(inside_nodes), len(inside_nodes), "all"),
             "Wiener: whole raster deconvolved, cropped to the pixel")
        c.ok(abs(w["x0_um"] - inside_nodes[0]) < 1e-9, "Wiener map starts at the first node inside")
    c.ok(count(scan) < count(scan, 0.6) < N * N, "the regions differ on this raster")

    # the geometry fit through the API: the document's geometry member, and the
    # chi2 at the fitted geometry no larger than at the written one (the fit starts there and
    # only goes down)
    r = d.post("/api/fits", dict(base, fit_geometry=True, geometry_r=5))
    c.status(r, 202, "upload with fit_geometry")
    j = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
    c.ok(j, "geometry fit done")
    if j:
        c.eq((j["params"].get("fit_geometry"), j["params"].get("geometry_r")), (True, 5),
             "job params record the geometry fit")
        res = d.get("/api/fits/%d" % j["fit_id"]).json()["result"]
        g = res.get("geometry", {})
        keys = ["spot_radius_um", "spot_radius_um_err", "dx_um", "dx_um_err", "dy_um",
                "dy_um_err", "chi2_fixed", "chi2_fitted"]
        if "error" in g:
            c.ok(False, "geometry failed: %s" % g["error"])
        else:
            c.ok(all(isinstance(g.get(k), (int, float)) for k in keys),
                 "geometry has the contract's fields: %r" % sorted(g))
            c.ok(g["chi2_fitted"] <= g["chi2_fixed"] * (1 + 1e-9),
                 "chi2 fitted %r <= fixed %r" % (g.get("chi2_fitted"), g.get("chi2_fixed")))
            c.ok("geometry" in res["timing_ms"], "timing_ms has geometry")
            c.eq(g.get("model"), "kriged", "the geometry is refined under the kriged model by default")
            kf = g.get("kriged_fit") or {}
            c.ok(isinstance(kf.get("chi2_red"), (int, float)) and kf["chi2_red"] > 0,
                 "kriged_fit carries the kriged model's chi2_red: %r" % kf)
    # the r x r map's geometry, asked: recorded in the job and said in the document
    r = d.post("/api/fits", dict(base, fit_geometry=True, geometry_r=5, geometry_model="map"))
    c.status(r, 202, "upload with geometry_model map")
    j = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
    c.ok(j, "map geometry fit done")
    if j:
        c.eq(j["params"].get("geometry_model"), "map", "job params record geometry_model")
        g = d.get("/api/fits/%d" % j["fit_id"]).json()["result"].get("geometry", {})
        c.eq((g.get("model"), g.get("kriged_fit")), ("map", None), "the map's geometry, not refined")

    # the kriged map (fit/krige.h) through the API: the result's kriged_map, number for number
    # the `ips fit --krige` document's of the same scan file
    r = d.post("/api/fits", dict(base, krige=True))
    c.status(r, 202, "upload with krige")
    j = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
    c.ok(j, "kriged fit done")
    if j:
        c.eq(j["params"].get("krige"), True, "job params record krige")
        res = d.get("/api/fits/%d" % j["fit_id"]).json()["result"]
        k, rec = res.get("kriged_map") or {}, res["recommended_r"]
        F = rec * -(-24 // rec)
        c.eq((k.get("grid"), k.get("r"), len(k.get("S", []))), (F, rec, F * F),
             "kriged_map on the %d x %d grid of the recommended r = %d" % (F, F, rec))
        c.ok("krige" in res["timing_ms"], "timing_ms has krige")
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "scan.json")
            with open(path, "w") as f:
                json.dump(scan, f)
            out = subprocess.run([argv[2], "fit", path, "--r-min", "1", "--r-max", "3",
                                  "--wiener", "--krige"], capture_output=True, text=True)
            kc = json.loads(out.stdout).get("kriged_map", {}) if out.returncode == 0 else {}
        # the same to rounding, not bit for bit: the likelihood's sums come from the CBLAS each
        # binary links (ips: GSL's own, statically; ipsd: the shared one)
        def rel(a, b):
            return max((abs(x - y) / max(abs(x), abs(y), 1e-300) for x, y in zip(a, b)),
                       default=1.0) if a and b and len(a) == len(b) else 1.0
        d_s, d_e = rel(kc.get("S"), k.get("S")), rel(kc.get("S_err"), k.get("S_err"))
        c.ok(d_s < 1e-8 and d_e < 1e-6,
             "ips fit --krige gives the same kriged map (S within %.1e, S_err %.1e)" % (d_s, d_e))
    r = d.post("/api/fits", dict(base, map="recommended"))
    j = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
    if j:
        c.ok("kriged_map" not in d.get("/api/fits/%d" % j["fit_id"]).json()["result"],
             "\"map\": \"recommended\" without krige: no kriged_map")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
