#!/usr/bin/env python3
"""test_import_fits.py IPS [IPSD]: `ips import-fits` and POST /api/fits's scan_fits, a lab's FITS scan cube as a scan file
(docs/contracts.md, "FITS scan cube"), with astropy (Debian's python3-astropy) as the independent
writer of the cube.

The simulated bench rasters one scan; `ips simulate --pixel DC,DR --all-points` writes three of
its sub-frame pixels' responses into a 3-column x 2-row sub-frame (the POI at its FITS column 2,
row 1; the other three pixels hold constants). astropy writes them as the cube a lab would: plane k the means at position k (float64),
the positions (relative to the POI's corner) in the binary table POSITIONS, the sensor constants
as header keywords with 17 significant digits. Then:

- the POI's import equals the simulator's scan file point for point, bit for bit (positions,
  signals and every constant), with the inside-only default and with --all-points; `ips fit` of
  it gives the same document as of the original (timings aside);
- another pixel (--pixel 1,0 and -1,1): its signals bit for bit, its positions within 1e-12 um
  (the cube holds the POI's positions; x - pitch in double and the simulator's own subtraction
  from the stage position differ by rounding), the same inside points;
- a NaN in the cube becomes null (a non-finite point the fit counts); per-row NCOMBINE / EXPTIME
  columns that agree are accepted; a uint16 cube (BITPIX 16, BZERO 32768) reads as its integers;
  stdin / stdout work as files do;
- bad input (not FITS, truncated, a missing keyword or column, wrong dimensions, a non-finite
  position, rows that disagree, a pixel outside the cube, a unit that is not um, ...) exits 2
  with one line on stderr naming what is wrong, and writes no file.
With IPSD, a real ipsd: POST /api/fits with the cube as scan_fits (base64) fits the same scan
file as an upload of the import (the stored results equal, timings aside), for the POI and for
pixel (1, 0) with all_points; bad cubes are 422 naming scan_fits.data / scan_fits.dcol; a cube
of a million one-byte points is 413 naming scan_fits.data, refused before its scan file is built
(ipsd's peak memory grows by little).
Exits 77 (skipped) without astropy."""
import base64
import json
import os
import subprocess
import sys
import tempfile

from debian_python import rerun_under_debian_python
from fitdoc import untimed
from ipsd_http import Checks, Ipsd

try:
    import numpy as np
    from astropy.io import fits
except ImportError:
    rerun_under_debian_python()  # Debian's python3-astropy is for Debian's python3
    print("astropy is missing (Debian: python3-astropy): skipped")
    sys.exit(77)

COLS, ROWS = (-1, 0, 1), (0, 1)  # the sub-frame pixels (dcol, drow) in the cube
SIMULATED = ((0, 0), (1, 0), (-1, 1))  # the others hold a constant: each simulation takes time
POICOL, POIROW = 2, 1            # the POI (0, 0): FITS column 2, row 1
SIM = ["--seed", "7", "--area", "3", "--step", "0.6", "--subframe", "3", "--frames", "4"]
CONSTS = {"PITCH": "pitch_um", "SPOTRAD": "spot_radius_um", "BIAS": "bias_dn",
          "GAIN": "gain_e_per_dn", "RDNOISE": "read_noise_e", "NCOMBINE": "frames",
          "SATURATE": "full_scale_dn"}
KEYS = ("pitch_um", "spot_radius_um", "bias_dn", "gain_e_per_dn", "read_noise_e", "frames",
        "full_scale_dn")


def run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, **kw)


def simulate(c, ips, t, name, extra):
    path = os.path.join(t, name)
    p = run([ips, "simulate"] + SIM + extra + ["-o", path])
    c.ok(p.returncode == 0, "ips simulate %r: %s" % (extra, p.stderr))
    with open(path) as f:
        return json.load(f)


def exact_card(key, value, comment):
    """A header card with repr's 17 significant digits (astropy's own formatting keeps 16, which
    can be one ulp off): what an exact writer (cfitsio's fits_write_key_dbl, -17) writes."""
    text = repr(float(value)) if isinstance(value, float) else str(value)
    return fits.Card.fromstring("%-8s= %20s / %s" % (key, text, comment))


def cube_hdul(scans, poi, **change):
    """The cube of the six pixels' scans as an astropy HDUList; change edits it (see below)."""
    n = len(poi["x_um"])
    data = np.empty((n, len(ROWS), len(COLS)), dtype=np.float64)
    for j, dr in enumerate(ROWS):
        for i, dc in enumerate(COLS):
            # None (a JSON null) never occurs in these scans; NaN would stand for it
            data[:, j, i] = np.array(scans[(dc, dr)]["signal_dn"], dtype=np.float64) \
                if (dc, dr) in scans else 1000.0 + 10 * i + j
    prim = fits.PrimaryHDU(data)
    prim.header["BUNIT"] = ("DN", "mean of NCOMBINE frames, bias included")
    for key, field in CONSTS.items():
        prim.header.append(exact_card(key, poi[field], field))
    prim.header["POICOL"] = (POICOL, "pixel of interest: FITS column (axis 1)")
    prim.header["POIROW"] = (POIROW, "pixel of interest: FITS row (axis 2)")
    cols = [fits.Column(name="X_UM", format="D", unit="um", array=np.array(poi["x_um"])),
            fits.Column(name="Y_UM", format="D", unit="um", array=np.array(poi["y_um"]))]
    for name, arr in change.get("columns", {}).items():
        cols.append(fits.Column(name=name, format="D", array=np.array(arr, dtype=np.float64)))
    tab = fits.BinTableHDU.from_columns(cols)
    tab.header["EXTNAME"] = "POSITIONS"
    return fits.HDUList([prim, tab])


def same_scan(c, got, want, what, pos_tol=0.0):
    for k in KEYS:
        c.eq(got.get(k), want[k], "%s: %s" % (what, k))
    c.eq(len(got["x_um"]), len(want["x_um"]), what + ": points")
    if len(got["x_um"]) != len(want["x_um"]):
        return
    c.eq(got["signal_dn"], want["signal_dn"], what + ": signal_dn bit for bit")
    for axis in ("x_um", "y_um"):
        if pos_tol == 0:
            c.eq(got[axis], want[axis], "%s: %s bit for bit" % (what, axis))
        else:
            worst = max(abs(a - b) for a, b in zip(got[axis], want[axis]))
            c.ok(worst <= pos_tol, "%s: %s within %g um (worst %g)" % (what, axis, pos_tol, worst))


def import_fits(ips, cube, out, *args):
    return run([ips, "import-fits", cube, "-o", out] + list(args))


def load(path):
    with open(path) as f:
        return json.load(f)


def fit_doc(ips, path):
    p = run([ips, "fit", path])
    doc = json.loads(p.stdout) if p.returncode == 0 else None
    return p.returncode, untimed(doc)  # timings vary from run to run


def card(text):
    """One 80-byte header card."""
    return text.ljust(80).encode()


def patched(t, good, name, hdu, key, new):
    """good's bytes with the card of key in header hdu (0 primary, 1 the table) replaced by the
    card new, written as name.fits: a raw edit no FITS writer would make."""
    with open(good, "rb") as f:
        body = bytearray(f.read())
    start = 0 if hdu == 0 else next(i for i in range(2880, len(body), 2880)
                                    if body[i:i + 9] == b"XTENSION=")
    at = next(i for i in range(start, len(body), 80) if body[i:i + 8] == key.ljust(8).encode())
    body[at:at + 80] = card(new)
    path = os.path.join(t, name + ".fits")
    with open(path, "wb") as f:
        f.write(body)
    return path


def three_points(t):
    """A 1 x 1 x 3 cube with positions (0.3, 0.3), (0.9, 0.9), (1.5, 1.5) in two D columns: its
    table's data fit in one 2880-byte block, so a wrong NAXIS1 still finds the table."""
    prim = fits.PrimaryHDU(np.full((3, 1, 1), 100.0))
    for key, value in (("PITCH", 6.0), ("SPOTRAD", 1.0), ("BIAS", 0.0), ("GAIN", 1.0),
                       ("RDNOISE", 1.0), ("NCOMBINE", 1), ("POICOL", 1), ("POIROW", 1)):
        prim.header[key] = value
    xy = np.array([0.3, 0.9, 1.5])
    tab = fits.BinTableHDU.from_columns([fits.Column(name="X_UM", format="D", array=xy),
                                         fits.Column(name="Y_UM", format="D", array=xy)])
    tab.header["EXTNAME"] = "POSITIONS"
    path = os.path.join(t, "three.fits")
    fits.HDUList([prim, tab]).writeto(path, overwrite=True)
    return path


def bad_inputs(c, ips, t, scans, poi, good):
    """Each broken cube: exit 2, one line on stderr naming what is wrong, no file written."""
    def variant(name, edit):
        h = cube_hdul(scans, poi)
        edit(h)
        path = os.path.join(t, name + ".fits")
        h.writeto(path, overwrite=True)
        return path

    def drop(key):
        return lambda h: h[0].header.remove(key)

    def set_key(key, value):
        def edit(h):
            h[0].header[key] = value
        return edit

    def nan_x(h):
        h[1].data["X_UM"][3] = np.nan

    def inf_x(h):
        h[1].data["X_UM"][3] = np.inf

    def flat(h):
        h[0].data = h[0].data[0]

    def short_table(h):
        h[1] = fits.BinTableHDU(h[1].data[:-1], header=h[1].header)

    def no_table(h):
        del h[1]

    def rename_table(h):
        h[1].header["EXTNAME"] = "SPOTS"

    def no_y(h):
        t = h[1].columns
        h[1] = fits.BinTableHDU.from_columns([t["X_UM"]])
        h[1].header["EXTNAME"] = "POSITIONS"

    def mm(h):
        t = h[1].columns
        cols = [fits.Column(name="X_UM", format="D", unit="mm", array=h[1].data["X_UM"]),
                t["Y_UM"]]
        h[1] = fits.BinTableHDU.from_columns(cols)
        h[1].header["EXTNAME"] = "POSITIONS"

    def ncombine_rows(h):
        n = len(poi["x_um"])
        t = h[1].columns
        frames = np.full(n, float(poi["frames"]))
        frames[5] += 1
        h[1] = fits.BinTableHDU.from_columns(
            [t["X_UM"], t["Y_UM"], fits.Column(name="NCOMBINE", format="D", array=frames)])
        h[1].header["EXTNAME"] = "POSITIONS"

    cases = [
        ("missing GAIN", variant("nogain", drop("GAIN")), [], "GAIN"),
        ("missing SPOTRAD", variant("norad", drop("SPOTRAD")), [], "SPOTRAD"),
        ("missing POICOL", variant("nopoi", drop("POICOL")), [], "POICOL"),
        ("missing NCOMBINE", variant("noframes", drop("NCOMBINE")), [], "NCOMBINE"),
        ("negative GAIN", variant("neggain", set_key("GAIN", -1.0)), [], "GAIN"),
        ("PITCH a word", variant("pitchword", set_key("PITCH", "six")), [], "PITCH"),
        ("NCOMBINE 2.5", variant("halfframe", set_key("NCOMBINE", 2.5)), [], "NCOMBINE"),
        ("POICOL beyond NAXIS1", variant("poifar", set_key("POICOL", 4)), [], "POICOL"),
        ("a 2-D primary image", variant("flat", flat), [], "NAXIS"),
        ("table one row short", variant("short", short_table), [], "rows"),
        ("no table", variant("notable", no_table), [], "POSITIONS"),
        ("table of another name", variant("spots", rename_table), [], "POSITIONS"),
        ("no Y_UM column", variant("noy", no_y), [], "Y_UM"),
        ("X_UM in mm", variant("mm", mm), [], "need um"),
        ("a NaN position", variant("nanx", nan_x), [], "X_UM in row 4"),
        # cfitsio reads an infinity as undefined: the message must not call it NaN
        ("an infinite position", variant("infx", inf_x), [],
         "X_UM in row 4 is not a finite number (NaN, infinite or undefined)"),
        ("NCOMBINE differs in row 6", variant("ncombine", ncombine_rows), [], "row 6"),
        ("SIMPLE = F", patched(t, good, "simplef", 0, "SIMPLE", "SIMPLE  = %20s" % "F"), [],
         "SIMPLE = F"),
        ("BSCALE = NaN", patched(t, good, "bscale", 0, "BUNIT", "BSCALE  = %20s" % "NaN"), [],
         "BSCALE"),
        ("BZERO = 1e999", patched(t, good, "bzero", 0, "BUNIT", "BZERO   = %20s" % "1e999"), [],
         "BZERO"),
        ("TSCAL1 = NaN", patched(t, good, "tscal", 1, "TUNIT1", "TSCAL1  = %20s" % "NaN"), [],
         "TSCAL1"),
        ("TZERO1 = 1e999", patched(t, good, "tzero", 1, "TUNIT1", "TZERO1  = %20s" % "1e999"),
         [], "TZERO1"),
        # two D columns (16 bytes) in rows of 8: cfitsio read Y from the next row's X
        ("NAXIS1 8, two D columns", patched(t, three_points(t), "naxis1", 1, "NAXIS1",
                                            "NAXIS1  = %20s" % "8"), [], "NAXIS1 = 8"),
        # cfitsio 4.2 copies an unquoted 70-character TTYPE into a smaller buffer (the fortified
        # build aborts the process): every card's syntax is checked before cfitsio reads it
        ("TTYPE1 unquoted, 70 chars", patched(t, good, "longttype", 1, "TTYPE1",
                                              "TTYPE1  = " + "A" * 70), [], "TTYPE1"),
        ("a DEL byte in a card", patched(t, good, "delbyte", 1, "TUNIT1", "TUNIT1  = 'um\x7f'"),
         [], "not printable ASCII"),
        ("/dev/zero", "/dev/zero", [], "not a FITS file"),
        ("pixel outside the cube", good, ["--pixel", "2,0"], "outside"),
        ("pixel above the cube", good, ["--pixel", "0,-1"], "outside"),
        ("--pixel one number", good, ["--pixel", "1"], "--pixel"),
        ("no such file", os.path.join(t, "missing.fits"), [], "missing.fits"),
    ]
    # not FITS at all, an empty file, a FITS file cut short
    notfits = os.path.join(t, "notfits.fits")
    with open(notfits, "w") as f:
        json.dump(poi, f)
    empty = os.path.join(t, "empty.fits")
    open(empty, "w").close()
    cut = os.path.join(t, "cut.fits")
    with open(good, "rb") as f:
        body = f.read()
    with open(cut, "wb") as f:
        f.write(body[:2880 * 2 + 100])
    cut_table = os.path.join(t, "cut_table.fits")
    with open(cut_table, "wb") as f:
        f.write(body[:len(body) - 2880 * 3])
    cases += [("a JSON file", notfits, [], "not a FITS file"),
              ("cut inside the table", cut_table, [], "inside table POSITIONS"),
              ("an empty file", empty, [], "not a FITS file"),
              ("a truncated file", cut, [], "cut.fits")]
    for what, path, args, word in cases:
        out = os.path.join(t, "bad-out.json")
        p = run([ips, "import-fits", path, "-o", out] + args, timeout=120)
        c.ok(p.returncode == 2 and word in p.stderr and p.stderr.count("\n") == 1 and
             p.stderr.startswith("ips import-fits: "),
             "%s: exit 2, one line naming %r (exit %d, %r)" % (what, word, p.returncode, p.stderr))
        c.ok(not os.path.exists(out), what + ": no file written")
        print("  %-26s %s" % (what, p.stderr.strip()))
    p = run([ips, "import-fits", good])
    c.ok(p.returncode == 2 and "-o" in p.stderr, "no -o: exit 2 (%r)" % p.stderr)


def api_fit_result(c, d, body, what):
    """POSTs body to /api/fits and returns the stored fit's result (timings aside), or None."""
    r = d.post("/api/fits", body)
    c.status(r, 202, what)
    job = d.wait_job(r.json()["job"]["id"], "done") if r.status == 202 else None
    c.ok(job and job.get("fit_id"), what + ": the job is done with a fit")
    if not job or not job.get("fit_id"):
        return None
    return untimed(d.get("/api/fits/%d" % job["fit_id"]).json().get("result") or {})


def api_checks(c, ipsd, t, good, poi, pixel_file, daemons):
    """POST /api/fits with scan_fits against the same upload as a scan file."""
    d = Ipsd(ipsd, t).start()
    daemons.append(d)
    with open(good, "rb") as f:
        b64 = base64.b64encode(f.read()).decode()
    opts = {"r_max": 4}
    want = api_fit_result(c, d, dict(opts, scan=poi), "upload of the POI's scan file")
    got = api_fit_result(c, d, dict(opts, scan_fits={"data": b64}), "scan_fits, the POI")
    c.ok(want and got == want, "scan_fits: the POI's fit equals the scan file's")
    want = api_fit_result(c, d, dict(opts, scan=load(pixel_file)), "upload of pixel 1,0, all")
    got = api_fit_result(c, d, dict(opts, scan_fits={"data": b64, "dcol": 1, "drow": 0,
                                                     "all_points": True}),
                         "scan_fits, pixel 1,0, all points")
    c.ok(want and got == want, "scan_fits: pixel 1,0's fit equals its import's")
    notfits = base64.b64encode(json.dumps(poi).encode()).decode()
    for body, field, what in (
            ({"scan_fits": {"data": "not base64!"}}, "scan_fits.data", "not base64"),
            ({"scan_fits": {"data": notfits}}, "scan_fits.data", "not FITS"),
            ({"scan_fits": {"data": b64[:len(b64) // 2]}}, "scan_fits.data", "cut short"),
            ({"scan_fits": {"data": b64, "dcol": 5}}, "scan_fits.dcol", "pixel outside"),
            ({"scan_fits": {"data": b64, "pixel": 1}}, "scan_fits.pixel", "unknown member"),
            ({"scan_fits": {}}, "scan_fits.data", "no data"),
            ({"scan": poi, "scan_fits": {"data": b64}}, "scan_fits", "both scan and scan_fits"),
            ({}, "scan", "neither")):
        c.error(d.post("/api/fits", body), 422, field, "POST /api/fits, " + what)
    for name, (hdu, key, text, word) in {
            "SIMPLE = F": (0, "SIMPLE", "SIMPLE  = %20s" % "F", "SIMPLE"),
            "TZERO1 = 1e999": (1, "TUNIT1", "TZERO1  = %20s" % "1e999", "TZERO1"),
            "NAXIS1 8": (1, "NAXIS1", "NAXIS1  = %20s" % "8", "NAXIS1")}.items():
        src = three_points(t) if key == "NAXIS1" else good
        with open(patched(t, src, "api", hdu, key, text), "rb") as f:
            data = base64.b64encode(f.read()).decode()
        r = d.post("/api/fits", {"scan_fits": {"data": data}})
        c.error(r, 422, "scan_fits.data", "POST /api/fits, " + name)
        c.ok(word in r.text, "%s: named (%s)" % (name, r.text[:200]))
    # 1 x 1 x 1,040,000 one-byte points with one-byte positions inside the pixel: 4.17 MB of
    # base64, within --max-body, a hundred times --max-fit-points. Refused from the header
    # (all_points) or the cut (inside only) before the scan file's JSON is built: ipsd's peak
    # memory (VmHWM, the kernel's count) grows by little, not by the ~300 MB it took
    n = 1040000
    prim = fits.PrimaryHDU(np.full((n, 1, 1), 100, dtype=np.uint8))
    for key, value in (("PITCH", 6.0), ("SPOTRAD", 1.0), ("BIAS", 0.0), ("GAIN", 1.0),
                       ("RDNOISE", 1.0), ("NCOMBINE", 1), ("POICOL", 1), ("POIROW", 1)):
        prim.header[key] = value
    pos = np.full(n, 3, dtype=np.uint8)
    tab = fits.BinTableHDU.from_columns([fits.Column(name="X_UM", format="B", array=pos),
                                         fits.Column(name="Y_UM", format="B", array=pos)])
    tab.header["EXTNAME"] = "POSITIONS"
    big = os.path.join(t, "big.fits")
    fits.HDUList([prim, tab]).writeto(big)
    with open(big, "rb") as f:
        data = base64.b64encode(f.read()).decode()

    def hwm_kb():
        with open("/proc/%d/status" % d.proc.pid) as f:
            return int(next(l for l in f if l.startswith("VmHWM:")).split()[1])

    before = hwm_kb()
    r = d.post("/api/fits", {"scan_fits": {"data": data, "all_points": True}})
    c.error(r, 413, "scan_fits.data", "a million points, all_points: 413 from the header")
    c.ok("NAXIS3" in r.text and "--max-fit-points" in r.text, "named: " + r.text[:300])
    r = d.post("/api/fits", {"scan_fits": {"data": data}})
    c.error(r, 413, "scan_fits.data", "a million points inside the pixel: 413 from the cut")
    c.ok("--max-fit-points" in r.text, "named: " + r.text[:300])
    grew = (hwm_kb() - before) / 1024
    c.ok(grew < 120, "ipsd's peak memory grew by %.0f MB (< 120) for a %.1f MB body"
         % (grew, len(data) / 1e6))
    print("  a million-point cube: peak memory +%.0f MB for a %.1f MB body" % (grew, len(data) / 1e6))
    c.eq(d.stop_term(), 0, "ipsd: SIGTERM, exit 0")


def main():
    ips = sys.argv[1]
    ipsd = sys.argv[2] if len(sys.argv) > 2 else None
    daemons = []
    c = Checks()
    with tempfile.TemporaryDirectory() as t:
        # one raster, six pixels of it (all positions each), and the POI's inside-only file
        scans = {(dc, dr): simulate(c, ips, t, "p%d%d.json" % (dc, dr),
                                    ["--pixel", "%d,%d" % (dc, dr), "--all-points"])
                 for dc, dr in SIMULATED}
        poi_all = scans[(0, 0)]
        poi_path = os.path.join(t, "poi.json")
        poi = simulate(c, ips, t, "poi.json", [])
        c.ok(0 < len(poi["x_um"]) < len(poi_all["x_um"]), "some positions lie outside the POI")
        good = os.path.join(t, "cube.fits")
        cube_hdul(scans, poi_all).writeto(good)

        # the POI: bit for bit, inside-only by default and every point with --all-points
        out = os.path.join(t, "imp.json")
        p = import_fits(ips, good, out)
        c.ok(p.returncode == 0 and p.stderr == "", "import the POI (%r)" % p.stderr)
        imp = load(out)
        same_scan(c, imp, poi, "POI")
        c.eq((imp.get("pixel"), imp.get("cube_size"), imp.get("cube_points")),
             ([0, 0], [3, 2], len(poi_all["x_um"])), "POI: provenance metadata")
        p = import_fits(ips, good, os.path.join(t, "imp_all.json"), "--all-points")
        c.ok(p.returncode == 0, "import the POI, all points (%r)" % p.stderr)
        same_scan(c, load(os.path.join(t, "imp_all.json")), poi_all, "POI, all points")

        # ips fit: the same document from the import as from the simulator's file
        rc0, want = fit_doc(ips, poi_path)
        rc1, got = fit_doc(ips, out)
        c.ok(rc0 == 0 and rc1 == 0 and want is not None, "ips fit of both (%d, %d)" % (rc0, rc1))
        c.ok(got == want, "ips fit: the import's document equals the original's (timings aside)")
        c.ok(want and want.get("recommended_r") and want["recommended_r"] >= 1,
             "the fit recommends a map (%r)" % (want or {}).get("recommended_r"))

        # other pixels: signals bit for bit, positions to rounding, the same inside points
        for dc, dr in ((1, 0), (-1, 1)):
            arg = "%d,%d" % (dc, dr)
            path = os.path.join(t, "imp%d%d.json" % (dc, dr))
            p = import_fits(ips, good, path, "--pixel", arg, "--all-points")
            c.ok(p.returncode == 0, "import --pixel %s (%r)" % (arg, p.stderr))
            same_scan(c, load(path), scans[(dc, dr)], "pixel %s, all" % arg, pos_tol=1e-12)
            want_in = simulate(c, ips, t, "in%d%d.json" % (dc, dr), ["--pixel", arg])
            path_in = os.path.join(t, "imp_in%d%d.json" % (dc, dr))
            p = import_fits(ips, good, path_in, "--pixel", arg)
            c.ok(p.returncode == 0, "import --pixel %s, inside (%r)" % (arg, p.stderr))
            same_scan(c, load(path_in), want_in, "pixel %s, inside" % arg, pos_tol=1e-12)

        # through ips's stdin and stdout, the same file
        with open(good, "rb") as f:
            p = subprocess.run([ips, "import-fits", "-", "-o", "-"], stdin=f, capture_output=True)
        c.ok(p.returncode == 0, "stdin to stdout (%r)" % p.stderr)
        same_scan(c, json.loads(p.stdout), poi, "stdin to stdout")

        # a NaN mean becomes null; per-row NCOMBINE / EXPTIME that agree are accepted
        n = len(poi_all["x_um"])
        h = cube_hdul(scans, poi_all, columns={"NCOMBINE": [poi["frames"]] * n,
                                               "EXPTIME": [0.125] * n})
        h[0].data[0, POIROW - 1, POICOL - 1] = np.nan
        nanc = os.path.join(t, "nan.fits")
        h.writeto(nanc)
        p = import_fits(ips, nanc, out, "--all-points")
        c.ok(p.returncode == 0, "NaN mean, NCOMBINE and EXPTIME columns (%r)" % p.stderr)
        imp = load(out)
        c.eq((imp["signal_dn"][0], imp["signal_dn"][1:], imp.get("exptime_s"), imp["frames"]),
             (None, poi_all["signal_dn"][1:], 0.125, poi["frames"]),
             "NaN mean as null, the rest bit for bit, EXPTIME and NCOMBINE from the table")

        # an integer cube (uint16: BITPIX 16 with BZERO 32768, as cameras write): the values
        # cfitsio scales back are the integers astropy was given
        h = cube_hdul(scans, poi_all)
        ints = np.round(h[0].data).astype(np.uint16)
        h[0].data = ints
        intc = os.path.join(t, "uint16.fits")
        h.writeto(intc)
        c.eq((fits.getheader(intc)["BITPIX"], fits.getheader(intc)["BZERO"]), (16, 32768),
             "astropy wrote uint16 as BITPIX 16, BZERO 32768")
        p = import_fits(ips, intc, out, "--all-points")
        c.ok(p.returncode == 0, "uint16 cube (%r)" % p.stderr)
        c.eq(load(out)["signal_dn"], [float(v) for v in ints[:, POIROW - 1, POICOL - 1]],
             "uint16 cube: the integers")

        bad_inputs(c, ips, t, scans, poi_all, good)
        p = run([ips, "--help"])
        c.ok("import-fits" in p.stdout, "ips --help lists import-fits")
        if ipsd:
            try:
                api_checks(c, ipsd, t, good, poi, os.path.join(t, "imp10.json"), daemons)
            finally:
                for d in daemons:
                    d.cleanup()
    return c.finish()


if __name__ == "__main__":
    sys.exit(main())
