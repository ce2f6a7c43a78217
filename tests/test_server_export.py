#!/usr/bin/env python3
"""test_server_export.py IPSD IPS: calibrations leaving ipsd as FITS files, and jitter photometry
over them (docs/api.md, "FITS" and "Jitter photometry"), through a real ipsd.

A scan of a simulated pixel (its automatic fit becomes the POI's calibration) and uploads of two
neighbouring pixels' raster (fits promoted to those pixels) make three calibrations. Then:

- FITS, read back by astropy (an independent reader of the bytes; Debian's python3-astropy):
  GET /api/calibrations/{id}/map.fits, .../pixels/{col}/{row}/calibration.fits and the sensor's
  /api/sensors/{id}/calibrations.fits: every map value and every S_err equal to the API's JSON
  (bit for bit: both are doubles), the header numbers (OVERSAMP, PITCH, SUBPIX, WAVELEN, NA,
  SPOTRAD, I0, CHI2RED) and words (FITSTAT, NOISEMOD, SWVERS, CALBY, REASON, IPSMAP) and ids (CALIBID,
  SCANID, FITID, CAL_MS, PIXCOL, PIXROW) equal to the JSON's; the sampling read through astropy's
  WCS: the first sample's centre at pitch / (2 r) um, the last at pitch - pitch / (2 r), and in
  the 'P' system at the pixel's column + 1 / (2 r); the file a multiple of 2880 bytes; 404 for
  unknown calibrations, pixels and sensors without maps; `ips export` of the JSON gives the same
  data and header values.
- Jitter (POST /api/jitter): a flat inline map adds no error; a Gaussian PSF far smaller than a
  sub-pixel, placed at sub-pixel centres, gives rho = that sub-pixel's S of the JSON map (the
  analytic limit) and rel_err = S_k / S_0 - 1; a PSF far larger than the pixel gives rho = the
  map's mean; the same request to the API and to `ips jitter` (the calibration's JSON and a
  series file) gives the same document; bad input is a 4xx naming the field.
Exits 77 (skipped) without astropy."""
import json
import math
import os
import subprocess
import sys
import urllib.parse

from debian_python import rerun_under_debian_python
import ipsd_http
from ipsd_http import Ipsd

try:
    import numpy as np
    from astropy.io import fits
    from astropy.wcs import WCS
except ImportError:
    rerun_under_debian_python()  # Debian's python3-astropy is for Debian's python3
    print("astropy is missing (Debian: python3-astropy): skipped")
    sys.exit(77)

POI = (40, 30)
PITCH = 6.0


def header_checks(c, h, cal, what):
    """The header of one map's extension against the calibration's JSON."""
    opt = cal["optics"]
    r = cal["r"]
    want = {"OVERSAMP": r, "PITCH": PITCH, "SUBPIX": PITCH / r, "CDELT1": PITCH / r,
            "CDELT2": PITCH / r, "CRVAL1": 0.0, "CRPIX1": 0.5, "CDELT1P": 1.0 / r,
            "CRVAL1P": cal["pixel"]["col"], "CRVAL2P": cal["pixel"]["row"],
            "PIXCOL": cal["pixel"]["col"], "PIXROW": cal["pixel"]["row"],
            "WAVELEN": None if opt["wavelength_nm"] is None else opt["wavelength_nm"] / 1000,
            "NA": opt["na"],
            "SPOTRAD": opt["spot_radius_um"], "I0": cal["I0"], "CHI2RED": cal["chi2_red"],
            "FITSTAT": cal["status"], "NOISEMOD": cal["noise_model"],
            "SWVERS": cal["software_version"], "CALBY": cal["by"], "REASON": cal["reason"],
            "CALIBID": cal["id"], "SENSORID": cal["sensor_id"], "SCANID": cal["scan_id"],
            "FITID": cal["fit_id"], "CAL_MS": cal["created_ms"], "CURRENT": cal["current"],
            "IPSMAP": cal["map"]}
    for k, v in want.items():
        got = h.get(k)
        if v is None or v == 0 and k in ("SCANID", "FITID"):
            # unknown (null in the JSON, or no scan): the keyword is left out
            c.ok(k not in h, "%s: %s = %r, want it left out" % (what, k, got))
            continue
        if isinstance(v, float) and not isinstance(v, bool):
            # 17 significant digits in the card: the same double (WAVELEN divides by 1000 here)
            ok = got is not None and abs(got - v) <= 1e-15 * abs(v)
        else:
            ok = got == v
        c.ok(ok, "%s: %s = %r, want %r" % (what, k, got, v))
    c.eq(h.get("BUNIT"), "", what + ": BUNIT (dimensionless)")


def map_checks(c, hdul, k, cal, what):
    """Extension pair k of a file against the calibration's JSON: data, S_err, header, WCS."""
    r = cal["r"]
    s, e = hdul["S", k], hdul["S_ERR", k]
    c.eq(s.data.shape, (r, r), what + ": S is r x r")
    c.eq([float(v) for v in s.data.ravel()], cal["S"], what + ": S row-major, equal to the JSON")
    c.eq([float(v) for v in e.data.ravel()], cal["S_err"], what + ": S_err equal to the JSON")
    header_checks(c, s.header, cal, what + " S")
    header_checks(c, e.header, cal, what + " S_ERR")
    # the resolution error, where the calibration knows it: an extension of its own after the
    # pairs, the JSON's numbers exactly
    if cal.get("S_res") is None:
        c.ok(("S_RES", k) not in hdul, what + ": no S_RES where the calibration has none")
    else:
        c.ok(("S_RES", k) in hdul, what + ": S_RES for a calibration with S_res")
        if ("S_RES", k) in hdul:
            rs = hdul["S_RES", k]
            c.eq([float(v) for v in rs.data.ravel()], cal["S_res"],
                 what + ": S_res equal to the JSON")
            header_checks(c, rs.header, cal, what + " S_RES")
    # the sampling, through astropy's WCS: sample (0, 0) is centred half a sub-pixel in
    w = WCS(s.header)
    x, y = w.wcs_pix2world([[0, 0], [r - 1, r - 1]], 0)[:, 0], None
    c.ok(abs(x[0] - PITCH / (2 * r)) < 1e-12 and abs(x[1] - (PITCH - PITCH / (2 * r))) < 1e-12,
         "%s: WCS of the first and last samples %r, want %g and %g um" %
         (what, list(x), PITCH / (2 * r), PITCH - PITCH / (2 * r)))
    wp = WCS(s.header, key="P")
    col = wp.wcs_pix2world([[0, 0]], 0)[0]
    c.ok(abs(col[0] - (cal["pixel"]["col"] + 1 / (2 * r))) < 1e-12 and
         abs(col[1] - (cal["pixel"]["row"] + 1 / (2 * r))) < 1e-12,
         "%s: WCS 'P' of the first sample %r, want the pixel + 1/(2r)" % (what, list(col)))


def read_fits(c, body, what):
    c.ok(len(body) > 0 and len(body) % 2880 == 0, "%s: %d bytes, a multiple of 2880" %
         (what, len(body)))
    import io
    return fits.open(io.BytesIO(body))


def test(c, t, argv, daemons):
    ips = argv[2]
    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start("--calibration-map", "recommended")  # the recommended map carries S_res
    sensor = d.post("/api/sensors", {"model": "IMX-F", "serial": "fits-1", "n_cols": 96,
                                     "n_rows": 64, "pitch_um": PITCH}).json()["id"]
    r = d.post("/api/scans", {"sensor_id": sensor, "poi": {"col": POI[0], "row": POI[1]},
                              "raster": {"area_px": 3, "step_um": 0.6, "sub_px": 3, "frames": 2},
                              "seed": 5})
    c.status(r, 202, "submit scan")
    scan, job = r.json()["scan"]["id"], r.json()["job"]["id"]
    c.ok(d.wait_job(job, "done"), "scan done")
    auto = d.get("/api/jobs?kind=fit&scan=%d" % scan).json()["items"]
    c.ok(auto and d.wait_job(auto[0]["id"], "done"), "the automatic fit done")
    # two more pixels: the neighbours' rasters fitted as calibrations of other sensor pixels
    for dcol, pix in ((1, (10, 11)), (-1, (12, 11))):
        pf = d.get("/api/scans/%d/pixels/%d/0" % (scan, dcol)).json()
        r = d.post("/api/fits", {"scan": pf, "sensor_id": sensor,
                                 "pixel": {"col": pix[0], "row": pix[1]}, "r_max": 3})
        c.status(r, 202, "upload pixel %r" % (pix,))
        c.ok(r.status == 202 and d.wait_job(r.json()["job"]["id"], "done"), "fit of %r" % (pix,))

    base = "/api/sensors/%d/pixels" % sensor
    cal = d.get("%s/%d/%d/calibration" % (base, POI[0], POI[1])).json()
    c.ok(cal.get("r", 0) >= 1, "the POI has a calibration")

    # ---- one calibration, by id and as the pixel's current one ----
    r = d.get("/api/calibrations/%d/map.fits" % cal["id"])
    c.status(r, 200, "map.fits")
    c.eq(r.headers.get("Content-Type"), "application/fits", "map.fits content type")
    c.ok("ipsd-calibration-%d.fits" % cal["id"] in (r.headers.get("Content-Disposition") or ""),
         "map.fits names the file")
    with read_fits(c, r.body, "map.fits") as h:
        c.ok(cal.get("S_res") is not None, "the automatic fit's calibration has S_res")
        c.eq(len(h), 3 + (cal.get("S_res") is not None), "map.fits: primary, S, S_ERR, S_RES")
        c.eq(h[0].header.get("NRESMAPS"), int(cal.get("S_res") is not None),
             "map.fits: NRESMAPS")
        c.eq((h[0].header.get("NMAPS"), h[0].header.get("ORIGIN"), h[0].header.get("SENSORID"),
              h[0].header.get("SENSMOD"), h[0].header.get("SENSSER")),
             (1, "ipsd", sensor, "IMX-F", "fits-1"), "map.fits: primary header")
        c.ok(h[0].data is None, "map.fits: the primary HDU has no data")
        map_checks(c, h, 1, cal, "map.fits")
    r = d.get("%s/%d/%d/calibration.fits" % (base, POI[0], POI[1]))
    c.status(r, 200, "calibration.fits")
    with read_fits(c, r.body, "calibration.fits") as h:
        map_checks(c, h, 1, cal, "calibration.fits")

    # ---- the sensor's file: every current calibration, by row then column ----
    cals = d.get("/api/calibrations?sensor=%d&current=1" % sensor).json()["items"]
    c.eq(len(cals), 3, "three current calibrations")
    cals.sort(key=lambda x: (x["pixel"]["row"], x["pixel"]["col"]))
    r = d.get("/api/sensors/%d/calibrations.fits" % sensor)
    c.status(r, 200, "calibrations.fits")
    with read_fits(c, r.body, "calibrations.fits") as h:
        c.eq(h[0].header.get("NMAPS"), 3, "calibrations.fits: NMAPS")
        n_res = sum(one.get("S_res") is not None for one in cals)
        c.eq(len(h), 7 + n_res, "calibrations.fits: primary, 3 x (S, S_ERR), the S_RES known")
        c.eq(h[0].header.get("NRESMAPS"), n_res, "calibrations.fits: NRESMAPS")
        # the pairs where they were before S_RES existed: HDUs 2k - 1 and 2k
        c.eq([(x.header.get("EXTNAME"), x.header.get("EXTVER")) for x in h[1:7]],
             [(nm, k) for k in (1, 2, 3) for nm in ("S", "S_ERR")],
             "calibrations.fits: the pairs first, in order")
        for k, one in enumerate(cals, 1):
            map_checks(c, h, k, one, "calibrations.fits map %d" % k)

    # ---- a sensor model outside ASCII: SENSMOD percent-encoded, as its comment says ----
    model = "Kamera-\u00dc 5%"
    uni = d.post("/api/sensors", {"model": model, "serial": "fits-3", "n_cols": 8,
                                  "n_rows": 8}).json()["id"]
    pf = d.get("/api/scans/%d/pixels/0/0" % scan).json()
    r = d.post("/api/fits", {"scan": pf, "sensor_id": uni, "pixel": {"col": 2, "row": 3},
                             "r_max": 2, "map": "recommended"})
    c.ok(r.status == 202 and d.wait_job(r.json()["job"]["id"], "done"), "fit for the UTF-8 model")
    r = d.get("/api/sensors/%d/pixels/2/3/calibration.fits" % uni)
    c.status(r, 200, "calibration.fits of the UTF-8 model's sensor")
    with read_fits(c, r.body, "UTF-8 model") as h:
        got = h[0].header.get("SENSMOD")
        c.eq((got, urllib.parse.unquote(got or "")), ("Kamera-%C3%9C 5%25", model),
             "SENSMOD: UTF-8 percent-encoded, decoding to the model")
        c.ok("percent-encoded" in h[0].header.comments["SENSMOD"], "its comment says so")

    # ---- what has no map ----
    c.error(d.get("/api/calibrations/999/map.fits"), 404, "", "unknown calibration")
    c.error(d.get("%s/1/1/calibration.fits" % base), 404, "", "pixel without a calibration")
    other = d.post("/api/sensors", {"model": "IMX-F", "serial": "fits-2", "n_cols": 8,
                                    "n_rows": 8}).json()["id"]
    c.error(d.get("/api/sensors/%d/calibrations.fits" % other), 404, "", "sensor without maps")
    c.error(d.get("/api/sensors/999/calibrations.fits"), 404, "", "unknown sensor")

    # ---- ips export of the JSON ----
    cal_path, out = os.path.join(t, "cal.json"), os.path.join(t, "cal.fits")
    with open(cal_path, "w") as f:
        json.dump(cal, f)
    p = subprocess.run([ips, "export", cal_path, "--pitch", str(PITCH), "-o", out],
                       capture_output=True, text=True)
    c.eq(p.returncode, 0, "ips export: " + p.stderr)
    if p.returncode == 0:
        with open(out, "rb") as f:
            with read_fits(c, f.read(), "ips export") as h:
                map_checks(c, h, 1, cal, "ips export")
    p = subprocess.run([ips, "export", cal_path, "-o", out], capture_output=True, text=True)
    c.ok(p.returncode == 2 and "--pitch" in p.stderr and p.stderr.count("\n") == 1,
         "ips export without --pitch: exit 2, one line naming it (%d %r)" %
         (p.returncode, p.stderr))

    # ---- jitter photometry ----
    rr, S = cal["r"], cal["S"]
    flat = d.post("/api/jitter", {"map": {"r": 2, "S": [1, 1, 1, 1]}, "pitch_um": PITCH,
                                  "psf": {"kind": "airy", "wavelength_nm": 550, "na": 0.25},
                                  "jitter": {"rms_um": 0.3, "samples": 200}})
    c.status(flat, 200, "jitter on a flat map")
    if flat.status == 200:
        j = flat.json()
        c.ok(j["err_rms"] < 1e-14 and j["err_max"] < 1e-14 and abs(j["rho0"] - 1) < 1e-14,
             "a flat map adds no error: %r" % {k: j[k] for k in ("err_rms", "err_max", "rho0")})
        c.ok(abs(j["psf"]["width_um"] - 1.22 * 0.55 / (2 * 0.25)) < 1e-12,
             "the Airy radius from wavelength and NA (eq. 1)")
        c.eq(j["n"], 200, "200 samples drawn")
    # a tiny Gaussian at sub-pixel centres: rho = that sub-pixel's S (S_ij at cell j*r+i)
    h = PITCH / rr
    cells = [(0, 0), (rr - 1, 0), (rr - 1, rr - 1), (rr // 2, rr - 1)]
    x0 = y0 = h / 2
    dx = [(i + 0.5) * h - x0 for i, _ in cells]
    dy = [(j + 0.5) * h - y0 for _, j in cells]
    r = d.post("/api/jitter", {"calibration_id": cal["id"], "position_um": {"x": x0, "y": y0},
                               "psf": {"kind": "gauss", "sigma_um": 1e-3},
                               "jitter": {"dx_um": dx, "dy_um": dy},
                               "measured": [100.0] * len(dx)})
    c.status(r, 200, "jitter with a tiny Gaussian")
    if r.status == 200:
        j = r.json()
        got = [s["rho"] for s in j["samples"]]
        want = [S[jj * rr + i] for i, jj in cells]
        c.ok(all(abs(a - b) <= 1e-12 * abs(b) for a, b in zip(got, want)),
             "tiny PSF: rho = S of the cell under the star: %r, want %r" % (got, want))
        c.ok(all(abs(s["rel_err"] - (w / S[0] - 1)) < 1e-12 for s, w in zip(j["samples"], want)),
             "rel_err = S_k / S_0 - 1")
        c.ok(all(abs(s["corrected"] - 100.0 / w) < 1e-9 for s, w in zip(j["samples"], want)),
             "corrected = measured / rho")
        c.eq(j["calibration_ids"], [cal["id"]], "the calibration used")
    # a Gaussian far larger than the pixel: rho = the map's mean
    r = d.post("/api/jitter", {"sensor_id": sensor, "col": POI[0], "row": POI[1],
                               "psf": {"kind": "gauss", "sigma_um": 6000},
                               "jitter": {"rms_um": 0.5, "samples": 10}})
    c.status(r, 200, "jitter with a huge Gaussian")
    if r.status == 200:
        mean = sum(S) / len(S)
        c.ok(abs(r.json()["rho0"] - mean) < 1e-6, "huge PSF: rho = the map's mean %r, got %r" %
             (mean, r.json()["rho0"]))
    # the API and ips jitter give the same document (the Airy spot of the scan's optics)
    series = os.path.join(t, "series.txt")
    dx = [0.1 * math.sin(k) for k in range(20)]
    dy = [0.2 * math.cos(1.3 * k) for k in range(20)]
    with open(series, "w") as f:
        f.write("# dx dy\n" + "".join("%.17g %.17g\n" % v for v in zip(dx, dy)))
    r = d.post("/api/jitter", {"calibration_id": cal["id"], "samples": True,
                               "jitter": {"dx_um": dx, "dy_um": dy}})
    p = subprocess.run([ips, "jitter", "--map", cal_path, "--series", series, "--samples-out",
                        "--pitch", str(PITCH)], capture_output=True, text=True)
    c.eq((r.status, p.returncode), (200, 0), "jitter by the API and by ips: " + p.stderr)
    if r.status == 200 and p.returncode == 0:
        a, b = r.json(), json.loads(p.stdout)
        c.ok(abs(a["psf"]["width_um"] - cal["optics"]["spot_radius_um"]) < 1e-15,
             "the default PSF is the calibration's spot")
        c.eq(a, b, "the API's document is ips jitter's")
        c.ok(a["err_rms"] > 0, "the measured map adds an error")
    bad = os.path.join(t, "bad.txt")
    with open(bad, "w") as f:
        f.write("0.1 0.2\n0.3\n")
    for args, word in ((["--map", cal_path], "--rms"), (["--map", cal_path, "--series", bad],
                                                         "line 2"),
                       (["--map", cal_path, "--rms", "0.1", "--psf", "gauss"], "--sigma")):
        p = subprocess.run([ips, "jitter"] + args, capture_output=True, text=True)
        c.ok(p.returncode == 2 and word in p.stderr and p.stderr.count("\n") == 1,
             "ips jitter %r: exit 2, one line naming %s (%d %r)" % (args, word, p.returncode,
                                                                   p.stderr))
    # bad input names the field
    c.error(d.post("/api/jitter", {"calibration_id": cal["id"]}), 422, "jitter", "no jitter")
    c.error(d.post("/api/jitter", {"calibration_id": cal["id"], "psf": {"kind": "moffat"},
                                   "jitter": {"rms_um": 1}}), 422, "psf.kind", "unknown psf")
    c.error(d.post("/api/jitter", {"jitter": {"rms_um": 1}}), 422, "calibration_id", "no map")
    c.error(d.post("/api/jitter", {"calibration_id": cal["id"],
                                   "jitter": {"dx_um": [0, 1], "dy_um": [0]}}), 422,
            "jitter.dy_um", "dx and dy of different lengths")
    c.error(d.post("/api/jitter", {"calibration_id": 999, "jitter": {"rms_um": 1}}), 404,
            "calibration_id", "unknown calibration")
    c.error(d.post("/api/jitter", {"map": {"r": 64, "S": [1.0] * 4096}, "pitch_um": PITCH,
                                   "psf": {"kind": "gauss", "sigma_um": 1},
                                   "jitter": {"rms_um": 1, "samples": 100000}}), 422,
            "jitter.samples", "too much work for one request")
    # a 0.012 um Airy spot (5 nm light) jittered 0.5 mm: 100 samples' cell integrals cross the
    # ~2000 Airy rings over the pixel each (~6e4 evaluations a sample; from the spot's foot they
    # crossed ~1e5 rings, 20 such samples held a thread 2 s when the fuzzer found them): computed,
    # a flat map's rho exactly 1
    near = d.post("/api/jitter", {"map": {"r": 2, "S": [1, 1, 1, 1]}, "pitch_um": PITCH,
                                  "psf": {"kind": "airy", "wavelength_nm": 5, "na": 0.25},
                                  "jitter": {"rms_um": 503, "samples": 100}})
    c.status(near, 200, "a tiny spot jittered far, 100 samples")
    if near.status == 200:
        c.ok(abs(near.json()["rho_mean"] - 1) < 1e-12 and near.json()["err_rms"] < 1e-12,
             "a flat map's rho is 1 far from the spot too: %r" % near.json()["rho_mean"])
    # one sample 0.5 mm away on a graded map: rho is the map's mean weighted by the cells' Airy
    # integrals, checked against `ips box` (the box path: polar angles about the spot, adaptive
    # quadrature; not the design matrix the API uses): 5e-13 apart (sweeping from the spot's foot
    # the design lost 7e-11 here)
    S4, R5 = [0.5, 1.5, 1.2, 0.8], 1.22 * 0.005 / (2 * 0.25)
    one = d.post("/api/jitter", {"map": {"r": 2, "S": S4}, "pitch_um": PITCH,
                                 "psf": {"kind": "airy", "wavelength_nm": 5, "na": 0.25},
                                 "position_um": {"x": PITCH / 2, "y": PITCH / 2},
                                 "samples": True, "jitter": {"dx_um": [300.0], "dy_um": [-400.0]}})
    c.status(one, 200, "one far sample on a graded map")
    if one.status == 200:
        cells = []
        for cj in range(2):
            for ci in range(2):
                h2 = PITCH / 2
                p = subprocess.run([ips, "box", repr(R5), repr(ci * h2), repr((ci + 1) * h2),
                                    repr(cj * h2), repr((cj + 1) * h2), repr(PITCH / 2 + 300.0),
                                    repr(PITCH / 2 - 400.0)], capture_output=True, text=True)
                cells.append(float(p.stdout.split()[0]))
        want = sum(a * b for a, b in zip(S4, cells)) / sum(cells)
        got = one.json()["samples"][0]["rho"]
        c.ok(abs(got - want) < 1e-11 * want and abs(want - 1) > 1e-4,
             "far sample: rho %r, by ips box %r" % (got, want))
    # 30000 of them: within samples x cells, but ~2e9 evaluations (fit_jitter_cost), a minute:
    # refused before any is computed
    far = d.post("/api/jitter", {"map": {"r": 2, "S": [1, 1, 1, 1]}, "pitch_um": PITCH,
                                 "psf": {"kind": "airy", "wavelength_nm": 5, "na": 0.25},
                                 "jitter": {"rms_um": 503, "samples": 30000}})
    c.error(far, 422, "jitter.samples", "a tiny spot jittered far: too many Airy rings")
    # a 0.2 um spot jittered 1 um, 100000 samples: ~1.8e8 evaluations by the estimate, 5 s of an
    # HTTP thread's CPU at the measured ~25 ns each (docs/operations.md): over the default bound
    r = d.post("/api/jitter", {"map": {"r": 1, "S": [1]}, "pitch_um": 6,
                               "psf": {"radius_um": 0.2},
                               "jitter": {"rms_um": 1, "samples": 100000}})
    c.error(r, 422, "jitter.samples", "a 0.2 um spot, 100000 samples: over the default bound")
    c.ok("4e+07" in r.text, "the message names the default bound: " + r.text[:300])
    c.ok("spot radii" in far.text and "--max-jitter-evals" in far.text,
         "the refusal says how far the samples reach and which option bounds it: %s" % far.text)
    # the same request on the command line: --max-evals refuses it before any integral, in one
    # line naming the option; a bound above its cost lets a small one through (the map's mean)
    flat = os.path.join(t, "flat2.json")
    with open(flat, "w") as f:
        json.dump({"r": 2, "S": [1, 1, 1, 1]}, f)
    p = subprocess.run([ips, "jitter", "--map", flat, "--pitch", str(PITCH), "--wavelength", "5",
                        "--na", "0.25", "--rms", "503", "--samples", "30000", "--max-evals", "2e8"],
                       capture_output=True, text=True)
    c.ok(p.returncode == 2 and "--max-evals" in p.stderr and "spot radii" in p.stderr and
         p.stderr.count("\n") == 1 and p.stdout == "",
         "ips jitter --max-evals: exit 2, one line, nothing computed (%d %r)" %
         (p.returncode, p.stderr))
    p = subprocess.run([ips, "jitter", "--map", flat, "--pitch", str(PITCH), "--rms", "0.3",
                        "--samples", "10", "--max-evals", "1e9"], capture_output=True, text=True)
    c.ok(p.returncode == 0 and p.stderr == "" and
         abs(json.loads(p.stdout)["rho_mean"] - 1) < 1e-12,
         "ips jitter under its bound: a flat map's rho is 1 (%d %r)" % (p.returncode, p.stderr))
    c.eq(d.stop_term(), 0, "SIGTERM: exit status 0")


if __name__ == "__main__":
    sys.exit(ipsd_http.main(test, sys.argv))
