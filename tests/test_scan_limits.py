#!/usr/bin/env python3
"""test_scan_limits.py IPSD IPS: a scan's defaults and limits are one definition
(instrument/scan_limits.h), so the three places a user meets them agree:

  - the OpenAPI document a real ipsd serves (GET /api/openapi.json, ScanCreate's members),
  - that ipsd's POST /api/scans (202, or 422 naming the field),
  - `ips simulate` (--dry-run: exit 0, or exit 2 with one line naming the option).

For every scan field the document's minimum and maximum are accepted by both, and the values just
outside are refused by both: min - 1 and max + 1 (odd fields: also min - 2, max + 2 and the even
min + 1 and max - 1), the next double above a real maximum, 0 and -1 for an exclusive minimum of
0. An exclusive minimum has no smallest value: a small value inside it is accepted instead (the
very smallest doubles are refused by the combined rules: eq. 1 or the points per axis leave
double range). The NA is the one field where `ips simulate` is narrower, by the simulated
bench's physics: its objective is dry, NA < 1 (instrument/sim.h).
The combined rules (whole steps, at most 10^6 raster points, frames x sub_px^2 <= 2^26) are
checked at their edges too. The document's defaults must equal what the API stores for a request
that gives nothing but the sensor and the POI, what `ips simulate --help` prints, and the paper's
scan (550 nm, NA 0.25, 5 x 5 pixels in 0.6 um steps, 9 x 9 sub-frames, 12 frames: independent of
the code). And no interface may refuse what it accepted before the limits were unified (the
contract only grows): the old ranges are written out below.

The API's accepted scans must not run: their POI (2000, 2000) is on the test's 4000 x 4000
sensor but outside the simulated camera's 256 x 256 array, so the scan worker fails each at its
configuration check before capturing anything; each is also cancelled at once.

Standard library only (http.client, json, subprocess)."""
import http.client
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

IPSD, IPS = sys.argv[1], sys.argv[2]
FAILS = []
CHECKS = 0

# the scan request's members and `ips simulate`'s options for them (None: no option)
FIELDS = [
    ("optics.wavelength_nm", "wavelength"),
    ("optics.na", "na"),
    ("optics.spot_radius_um", "radius"),
    ("raster.area_px", "area"),
    ("raster.step_um", "step"),
    ("raster.sub_px", "subframe"),
    ("raster.frames", "frames"),
    ("exposure_us", None),
    ("seed", "seed"),
]

# the paper's scan (section II.B): the defaults, from the paper, not from the code
PAPER = {"optics.wavelength_nm": 550, "optics.na": 0.25, "raster.area_px": 5,
         "raster.step_um": 0.6, "raster.sub_px": 9, "raster.frames": 12}

# values each interface accepted before the limits were one definition (api/api_scans.c:
# area 1..101, sub 3..99, frames 1..1000, NA <= 1.7, wavelength <= 1e5 nm, radius <= 1000 um,
# exposure <= 1e9 us; cli/cmd_simulate.c: area 1..50, subframe 3..63, frames 1..10000,
# wavelength 10..1e5 nm, NA 1e-3..0.999, radius and step 1e-3..1e3, grid 1..200): each must still
# be accepted, as the contracts only grow. Even areas, which `ips simulate` took, are the one
# exception (docs/instrument.md): 49 is the largest odd one.
OLD_API = {"optics.wavelength_nm": [1e-9, 1e5], "optics.na": [1e-9, 1.7],
           "optics.spot_radius_um": [1e-9, 1000], "raster.area_px": [1, 101],
           "raster.step_um": [1000], "raster.sub_px": [3, 99], "raster.frames": [1, 1000],
           "exposure_us": [1e-9, 1e9], "seed": [0, 4294967295]}
OLD_CLI = {"wavelength": [10, 100000], "na": [1e-3, 0.999], "radius": [1e-3, 1e3],
           "area": [1, 49], "step": [1e-3, 1e3], "subframe": [3, 63], "frames": [1, 10000],
           "seed": [0, 4294967295], "grid": [1, 200]}

PITCH = 6.0  # the test sensor's pitch and the simulated bench's (scene.h: the paper's 6 um)


def check(cond, msg):
    global CHECKS
    CHECKS += 1
    if not cond:
        FAILS.append(msg)
        print("FAIL: " + msg, file=sys.stderr)
    return cond


# ---- the server ----

class Server:
    def __init__(self, tmp):
        self.tmp = tmp
        port_file = os.path.join(tmp, "port")
        self.log = open(os.path.join(tmp, "ipsd.log"), "w")
        self.proc = subprocess.Popen(
            [IPSD, "--listen", "127.0.0.1:0", "--port-file", port_file, "--db",
             os.path.join(tmp, "ipsd.db")], stdout=self.log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + 60  # a generous deadline, polled: the machine may be busy
        self.port = None
        while time.monotonic() < deadline and self.proc.poll() is None:
            try:
                with open(port_file) as f:
                    text = f.read().strip()
                if text:
                    self.port = int(text)
                    break
            except FileNotFoundError:
                pass
            time.sleep(0.05)
        if self.port is None:
            self.stop()
            with open(os.path.join(tmp, "ipsd.log")) as f:
                sys.exit("ipsd did not start:\n" + f.read())

    def request(self, method, path, body=None):
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=120)
        headers = {}
        data = None
        if body is not None:
            data = json.dumps(body)
            headers["Content-Type"] = "application/json"
        conn.request(method, path, data, headers)
        resp = conn.getresponse()
        text = resp.read()
        conn.close()
        return resp.status, json.loads(text) if text else None

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.log.close()


def member(schema, path):
    """The schema of the ScanCreate member at a dotted path."""
    for seg in path.split("."):
        schema = schema["properties"][seg]
    return schema


def dig(d, path):
    """The value at a dotted path of a scan as the API returns it, or of `--dry-run`'s output."""
    for seg in path.split("."):
        d = d[seg]
    return d


def put(body, path, value):
    *outer, last = path.split(".")
    for seg in outer:
        body = body.setdefault(seg, {})
    body[last] = value


def js(v):
    """A JSON value as `ips simulate` takes it on its command line: repr keeps every digit."""
    return repr(v) if isinstance(v, float) else str(v)


# ---- the two interfaces ----

def api_scan(srv, sensor, edits):
    """POSTs a scan (a cheap valid one, changed by edits {path: value}); cancels an accepted one.
    Returns (status, body)."""
    body = {"sensor_id": sensor, "poi": {"col": 2000, "row": 2000},
            "raster": {"area_px": 1, "step_um": PITCH, "sub_px": 3, "frames": 1}}
    for path, value in edits.items():
        put(body, path, value)
    status, reply = srv.request("POST", "/api/scans", body)
    if status == 202:
        srv.request("POST", "/api/scans/%d/cancel" % reply["scan"]["id"])
    return status, reply


def api_case(sensors, path, v):
    """(sensor, edits) for field path = v, with companions that keep the combined rules
    satisfied (the cheap scan of api_scan, on the 6 um sensor, otherwise)."""
    edits = {path: v}
    if path == "raster.step_um":
        if v >= PITCH:
            return sensors[1000.0], edits  # 1 pixel of 1000 um: a whole number of such steps
        edits["raster.area_px"] = 1  # small steps: 1 pixel of 6 um, at most 999 of them
    if path == "optics.spot_radius_um":
        edits["optics.wavelength_nm"] = 1e-9  # keeps the NA of eq. 1 in range for a small R
    return sensors[PITCH], edits


def cli_case(opt, v):
    """The arguments for --opt v, with companions that keep the combined rules satisfied."""
    args = ["--" + opt, js(v)]
    if opt == "area":
        args += ["--step", js(PITCH)]  # area + 1 points a side: at most 1000
    if opt == "step":
        args += ["--grid", "1"]  # the bench's pitch is 6 um: a one-point grid takes any step
    if opt == "grid" and v > 1:
        args += ["--step", js(PITCH / v)]  # v points in v - 1 such steps lie inside the pixel
    return args


def api_accepts(srv, sensor, edits, what):
    status, reply = api_scan(srv, sensor, edits)
    check(status == 202, "API should accept %s: %s %s" % (what, status, reply))


def api_refuses(srv, sensor, edits, field, what):
    status, reply = api_scan(srv, sensor, edits)
    got = reply.get("error", {}).get("field") if isinstance(reply, dict) else None
    check(status == 422 and got == field,
          "API should refuse %s with 422 naming %s: %s %s" % (what, field, status, reply))


def cli(args):
    p = subprocess.run([IPS, "simulate", "--dry-run"] + args, capture_output=True, text=True,
                       timeout=120)
    return p.returncode, p.stdout, p.stderr


def cli_accepts(args, path=None, value=None):
    code, out, err = cli(args)
    ok = check(code == 0, "ips simulate %s should be accepted: exit %d, %s" %
               (" ".join(args), code, err.strip()))
    if ok and path:  # and the value was taken as given (the wavelength goes through um)
        got = dig(json.loads(out), path)
        check(math.isclose(got, value, rel_tol=1e-12),
              "ips simulate %s: %s is %r, want %r" % (" ".join(args), path, got, value))


def cli_refuses(args, option):
    code, out, err = cli(args)
    lines = err.splitlines()
    check(code == 2 and len(lines) == 1 and ("--" + option) in err,
          "ips simulate %s should exit 2 with one line naming --%s: exit %d, %r" %
          (" ".join(args), option, code, err))


# ---- what `ips simulate --help` says ----

def help_entries():
    """{option: (range text, default or None)} from the usage lines '--opt X  text (RANGE; default D)'."""
    p = subprocess.run([IPS, "simulate", "--help"], capture_output=True, text=True, timeout=120)
    check(p.returncode == 0, "ips simulate --help exits 0")
    out = {}
    for line in p.stdout.splitlines():
        m = re.match(r"\s+--([\w-]+) \S+\s.*\(([^()]*)\)\s*$", line)
        if m:
            parts = [s.strip() for s in m.group(2).split(";")]
            default = None
            for s in parts:
                if s.startswith("default "):
                    default = s[len("default "):]
                    try:
                        default = float(default)
                    except ValueError:  # --scene's
                        pass
            out[m.group(1)] = (parts[0], default)
    return out


def bounds_text(sch):
    """The range as `ips simulate --help` writes it, from the document."""
    if sch["type"] == "integer":
        return ("odd, " if sch.get("x-odd") else "") + "%d..%d" % (sch["minimum"], sch["maximum"])
    lo = sch.get("exclusiveMinimum", sch.get("minimum"))
    return ("> %.15g and <= %.15g" if "exclusiveMinimum" in sch else "%.15g..%.15g") % (
        lo, sch["maximum"])


def main():
    tmp = tempfile.mkdtemp(prefix="ipsd-limits-")
    srv = Server(tmp)
    try:
        run(srv)
    finally:
        srv.stop()
        shutil.rmtree(tmp, ignore_errors=True)
    print("%d checks, %d failed" % (CHECKS, len(FAILS)))
    sys.exit(1 if FAILS else 0)


def run(srv):
    status, doc = srv.request("GET", "/api/openapi.json")
    check(status == 200, "GET /api/openapi.json")
    scan_create = doc["components"]["schemas"]["ScanCreate"]
    schemas = {path: member(scan_create, path) for path, _ in FIELDS}

    # the document: every field bounded, with the paper's defaults, and no narrower than before
    for path, sch in schemas.items():
        lo = sch.get("minimum", sch.get("exclusiveMinimum"))
        check(lo is not None and "maximum" in sch, "%s has a minimum and a maximum" % path)
        check(("minimum" in sch) != ("exclusiveMinimum" in sch),
              "%s has one of minimum and exclusiveMinimum" % path)
        if sch.get("x-odd"):
            check(sch.get("not") == {"multipleOf": 2}, "%s: odd in JSON Schema terms" % path)
    for path, want in PAPER.items():
        check(schemas[path].get("default") == want,
              "%s defaults to %r, the paper's %r" % (path, schemas[path].get("default"), want))

    # a sensor for the scans (6 um), and one of 1000 um pixels, the only way a 1000 um step can
    # divide a raster into whole steps (area_px x pitch / step)
    sensors = {}
    for pitch in (PITCH, 1000.0):
        status, reply = srv.request("POST", "/api/sensors", {
            "model": "limits", "serial": "p%g" % pitch, "n_cols": 4000, "n_rows": 4000,
            "pitch_um": pitch})
        check(status == 201, "create the %g um sensor: %s %s" % (pitch, status, reply))
        sensors[pitch] = reply["id"]
    s6 = sensors[PITCH]

    # ---- defaults: the document, the API's stored scan, `ips simulate --help` ----
    status, reply = srv.request("POST", "/api/scans",
                                {"sensor_id": s6, "poi": {"col": 2000, "row": 2000}})
    check(status == 202, "a scan of defaults: %s %s" % (status, reply))
    scan_id, job = reply["scan"]["id"], reply["job"]
    srv.request("POST", "/api/scans/%d/cancel" % scan_id)
    status, stored = srv.request("GET", "/api/scans/%d" % scan_id)
    for path, opt in FIELDS:
        want = schemas[path].get("default")
        if want is None:
            continue
        got = job["params"]["seed"] if path == "seed" else dig(stored, path)
        check(math.isclose(got, want, rel_tol=1e-12),
              "stored default of %s: %r, the document's %r" % (path, got, want))
    R = 1.22 * 0.55 / (2 * 0.25)  # paper eq. 1 for its 550 nm and NA 0.25: 1.342 um
    check(math.isclose(stored["optics"]["spot_radius_um"], R, rel_tol=1e-12),
          "stored spot radius %r, eq. 1's %r" % (stored["optics"]["spot_radius_um"], R))
    helps = help_entries()
    for path, opt in FIELDS:
        if opt is None:
            continue
        sch = schemas[path]
        check(opt in helps, "ips simulate --help has --%s" % opt)
        if opt not in helps:
            continue
        rng, default = helps[opt]
        check(default == sch.get("default"),
              "--%s: --help's default %r, the document's %r" % (opt, default, sch.get("default")))
        check(rng == bounds_text(sch),
              "--%s: --help's range '%s', the document's '%s'" % (opt, rng, bounds_text(sch)))
    code, out, err = cli([])
    if check(code == 0, "ips simulate --dry-run with no options: %s" % err.strip()):
        d = json.loads(out)
        for path, opt in FIELDS:
            want = schemas[path].get("default")
            if opt is None or want is None:
                continue
            got = dig(d, path)
            check(math.isclose(got, want, rel_tol=1e-12),
                  "ips simulate's default %s %r, the document's %r" % (path, got, want))

    # ---- what was accepted before still is ----
    for path, values in OLD_API.items():
        for v in values:
            sensor, edits = api_case(sensors, path, v)
            api_accepts(srv, sensor, edits, "%s = %r (accepted before)" % (path, v))
    for opt, values in OLD_CLI.items():
        for v in values:
            cli_accepts(cli_case(opt, v))

    # ---- each field's range: its ends accepted, just outside refused, by both ----
    for path, opt in FIELDS:
        sch = schemas[path]
        hi = sch["maximum"]
        if sch["type"] == "integer":
            lo = sch["minimum"]
            inside, outside = [lo, hi], [lo - 1, hi + 1]
            if sch.get("x-odd"):  # even values inside the range too
                outside += [lo - 2, hi + 2, lo + 1, hi - 1]
        elif "exclusiveMinimum" in sch:
            lo = sch["exclusiveMinimum"]
            small = PITCH / 999 if path == "raster.step_um" else 1e-3  # see the docstring
            inside, outside = [small, hi], [lo, -1.0, math.nextafter(hi, math.inf)]
        else:
            lo = sch["minimum"]
            inside = [lo, hi]
            outside = [math.nextafter(lo, -math.inf), math.nextafter(hi, math.inf)]
        for v in inside:
            sensor, edits = api_case(sensors, path, v)
            api_accepts(srv, sensor, edits, "%s = %r" % (path, v))
        for v in outside:
            sensor, edits = api_case(sensors, path, v)
            api_refuses(srv, sensor, edits, path, "%s = %r" % (path, v))
        if opt is None:
            continue
        for v in inside:
            if opt == "na" and v >= 1:  # the simulated bench's objective is dry: NA < 1 (sim.h)
                cli_refuses(["--na", js(v)], "na")
                v = math.nextafter(1.0, 0.0)
            args = ["--step", js(v), "--area", "1"] if opt == "step" and v < PITCH else \
                cli_case(opt, v)
            cli_accepts(args, path, v)
        for v in outside:
            cli_refuses(cli_case(opt, v), opt)

    # ---- the grid of `ips simulate` (no API field): 1..1000 points a side inside the pixel ----
    check(helps.get("grid", ("",))[0] == "1..1000", "--help: --grid 1..1000: %r" %
          (helps.get("grid"),))
    cli_accepts(cli_case("grid", 1), "grid", 1)
    cli_accepts(cli_case("grid", 1000), "grid", 1000)  # 999 steps of 6/1000 um: 5.994 um
    cli_refuses(cli_case("grid", 0), "grid")
    cli_refuses(cli_case("grid", 1001), "grid")
    cli_refuses(["--grid", "11"], "grid")  # 10 steps of 0.6 um span the whole 6 um pixel

    # ---- the combined rules, at their edges ----
    # at most 10^6 points: 1 pixel of 6 um in 999 steps is 1000^2 points, in 1000 steps 1001^2
    api_accepts(srv, s6, {"raster.area_px": 1, "raster.step_um": PITCH / 999}, "10^6 points")
    api_refuses(srv, s6, {"raster.area_px": 1, "raster.step_um": PITCH / 1000}, "raster.step_um",
                "1001^2 points")
    cli_accepts(["--area", "1", "--step", js(PITCH / 999)])
    cli_refuses(["--area", "1", "--step", js(PITCH / 1000)], "step")
    # whole steps: 5 pixels of 6 um are not a whole number of 0.7 um steps
    api_refuses(srv, s6, {"raster.area_px": 5, "raster.step_um": 0.7}, "raster.step_um",
                "0.7 um steps")
    cli_refuses(["--step", "0.7"], "step")
    # frames x sub_px^2 <= 2^26 = 67108864: 1032 x 255^2 = 67105800, 1033 x 255^2 = 67170825
    api_accepts(srv, s6, {"raster.sub_px": 255, "raster.frames": 1032}, "1032 frames of 255^2")
    api_refuses(srv, s6, {"raster.sub_px": 255, "raster.frames": 1033}, "raster.frames",
                "1033 frames of 255^2")
    cli_accepts(["--subframe", "255", "--frames", "1032"])
    cli_refuses(["--subframe", "255", "--frames", "1033"], "frames")
    # eq. 1 at the ends of double precision: NA 5e-324 gives an infinite radius
    api_refuses(srv, s6, {"optics.na": 5e-324}, "optics.na", "NA 5e-324")
    # a radius needing NA > max: 550 nm focused to R = 0.1 um needs NA 3.4
    api_refuses(srv, s6, {"optics.spot_radius_um": 0.1}, "optics.spot_radius_um", "R = 0.1 um")


if __name__ == "__main__":
    main()
