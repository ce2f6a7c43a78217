#!/usr/bin/env python3
"""test_api_interp.py IPSD: the interpolated-map routes of a real ipsd (GET /api/fits/{id}/interp
and GET /api/calibrations/{id}/interp) against analytic facts. Python 3's standard library only.

It starts ipsd on a free loopback port (--listen 127.0.0.1:0, the port read from --port-file) with
a database in a temporary directory, uploads noise-free scan files to POST /api/fits, waits for
the fit jobs, and reads the interpolated maps:

- a uniform pixel: the interpolated map is flat (S = 1 everywhere, the maps have mean 1);
- a pixel whose sensitivity grows linearly along x, s(x) = 0.7 + 0.6 x / pitch (mean 1): the
  bicubic map is that line between the outermost sub-pixel centres and constant outside, the same
  in every row (x is the column, row-major y then x);
- for every r of the sweep, the map on an r x r grid is the fit's own S (the grid points are the
  sub-pixel centres), the corner points outside the outermost centres are S[0] (constant
  extension), r = 1 is constant, and r = 2, 3 (bilinear) stay within the map's range;
- the calibration route gives the stored calibration's map the same way;
- bad input: 4xx with the error body naming the field (n, r), 404 for unknown ids, 409 for an r
  whose fit has no map;
- ipsd exits 0 at SIGTERM (a sanitizer build's reports make it fail).

The scans use a spot far smaller than a sub-pixel (R = 0.005 um on 6 um pixels, points 0.125 um or
more from the pixel's edges), so a point's light falls in the sub-pixel under it: the fitted map
is then the sensitivity averaged over each sub-pixel, up to the spot's light beyond 0.125 um of
its centre: 1 - EE = J0(x)^2 + J1(x)^2 ~ 2 / (pi x) = 0.7 % at x = 3.83 * 0.125 / R (the Airy
pattern's encircled energy, Rayleigh's formula); the tolerance below (1 %) is that bound.

Exit 0 when every check passes, 1 otherwise.
"""
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

PITCH = 6.0
SPOT_R = 0.005     # um: far below the sub-pixel sizes (0.75 um at r = 8)
GRID = 24          # points per axis, at (m + 1/2) * pitch / GRID: 3 per sub-pixel at r = 8
I0 = 5000.0        # DN of the whole spot on a sensitivity-1 area
BIAS = 100.0
LEAK_TOL = 0.01    # the Airy energy beyond 0.125 um (see the docstring), relative
DEADLINE_S = 120   # generous: a sanitizer build on a busy machine

checks = 0
fails = 0


def check(cond, what, detail=''):
    global checks, fails
    checks += 1
    if not cond:
        fails += 1
        print(f'FAIL: {what}' + (f': {detail}' if detail else ''), file=sys.stderr)
    return cond


class Ipsd:
    """A real ipsd on 127.0.0.1 with a temporary database."""

    def __init__(self, binary, tmp):
        port_file = os.path.join(tmp, 'port')
        self.log = open(os.path.join(tmp, 'ipsd.log'), 'w')
        self.proc = subprocess.Popen(
            [binary, '--listen', '127.0.0.1:0', '--port-file', port_file,
             '--db', os.path.join(tmp, 'ipsd.db')], stdout=self.log, stderr=self.log)
        end = time.monotonic() + DEADLINE_S
        port = ''
        while time.monotonic() < end and self.proc.poll() is None:
            if os.path.exists(port_file):
                port = open(port_file).read().strip()
                if port.isdigit():
                    break
            time.sleep(0.05)
        if not port.isdigit():
            self.stop()
            raise SystemExit(f'ipsd did not start: {open(self.log.name).read()}')
        self.base = f'http://127.0.0.1:{port}'

    def req(self, method, path, body=None):
        """(status, parsed JSON body)."""
        data = json.dumps(body).encode() if body is not None else None
        r = urllib.request.Request(self.base + path, data=data, method=method)
        if data is not None:
            r.add_header('Content-Type', 'application/json')
        try:
            with urllib.request.urlopen(r, timeout=60) as resp:
                return resp.status, json.loads(resp.read())
        except urllib.error.HTTPError as e:
            return e.code, json.loads(e.read())

    def wait_job(self, job_id):
        """Polls the job until it has ended; returns it."""
        end = time.monotonic() + DEADLINE_S
        while time.monotonic() < end:
            _, job = self.req('GET', f'/api/jobs/{job_id}')
            if job['state'] in ('done', 'failed', 'cancelled'):
                return job
            time.sleep(0.1)
        raise SystemExit(f'job {job_id} did not end in {DEADLINE_S} s')

    def stop(self):
        """SIGTERM; checks the graceful exit (0: a sanitizer build's reports make it fail)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=DEADLINE_S)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.log.close()
        if not check(self.proc.returncode == 0, 'ipsd exits 0 at SIGTERM',
                     f'status {self.proc.returncode}'):
            print(open(self.log.name).read()[-4000:], file=sys.stderr)


def scan_file(sensitivity, points=None):
    """A noise-free scan file of a pixel with sensitivity(x_um, y_um), seen by a spot much smaller
    than a sub-pixel: signal = bias + I0 * s at the spot's centre."""
    pos = [(m + 0.5) * PITCH / GRID for m in range(GRID)]
    xy = points or [(x, y) for y in pos for x in pos]
    return {'pitch_um': PITCH, 'spot_radius_um': SPOT_R, 'bias_dn': BIAS, 'gain_e_per_dn': 3.153,
            'read_noise_e': 5.67, 'frames': 12, 'x_um': [p[0] for p in xy],
            'y_um': [p[1] for p in xy],
            'signal_dn': [BIAS + I0 * sensitivity(x, y) for x, y in xy]}


def fit_upload(d, body):
    status, reply = d.req('POST', '/api/fits', body)
    if not check(status == 202, 'upload accepted', f'{status} {reply}'):
        raise SystemExit(1)
    job = d.wait_job(reply['job']['id'])
    if not check(job['state'] == 'done' and job['fit_id'], 'fit job done', json.dumps(job)):
        raise SystemExit(1)
    status, fit = d.req('GET', f"/api/fits/{job['fit_id']}")
    check(status == 200, 'fit read back')
    return fit


def interp(d, path, what):
    status, m = d.req('GET', path)
    check(status == 200, f'{what}: 200', f'{status} {m}')
    return m


def clamp(p, r):
    """Output coordinate p (pitch units) moved onto the outermost sub-pixel centres of r."""
    return min(max(p, 0.5 / r), (r - 0.5) / r)


def check_geometry(d, fit):
    """The facts that hold for any map: through the centres, constant extension, r = 1 and
    bilinear ranges."""
    fid = fit['id']
    for f in fit['result']['fits']:
        r, S = f['r'], f['S']
        if S is None:
            continue
        m = interp(d, f'/api/fits/{fid}/interp?r={r}&n={r}', f'fit {fid} r = {r}, n = r')
        check(m['fit_id'] == fid and m['r'] == r and m['n'] == r and len(m['S']) == r * r,
              f'r = {r}: the reply names the fit, r and n', str({k: m[k] for k in m if k != 'S'}))
        check(all(abs(a - b) <= 1e-12 * max(1.0, abs(b)) for a, b in zip(m['S'], S)),
              f'r = {r}: on the r x r grid (the sub-pixel centres) the map is the fit\'s S')
        check(m['method'] == ('bicubic' if r >= 4 else 'bilinear' if r >= 2 else 'constant'),
              f'r = {r}: method {m["method"]}')
        n = 4 * r  # points 0 and 1 of each axis lie before the first centre 1 / (2r)
        m = interp(d, f'/api/fits/{fid}/interp?r={r}&n={n}', f'fit {fid} r = {r}, n = 4r')
        corner = [m['S'][j * n + i] for j in (0, 1) for i in (0, 1)]
        check(all(abs(v - S[0]) <= 1e-12 for v in corner),
              f'r = {r}: outside the outermost centres the corner takes S[0]', f'{corner}, {S[0]}')
        if r == 1:
            check(all(v == S[0] for v in m['S']), 'r = 1: the map is constant')
        if r in (2, 3):
            check(min(S) - 1e-12 <= min(m['S']) and max(m['S']) <= max(S) + 1e-12,
                  f'r = {r}: the bilinear map stays within the map\'s range')


def main():
    if len(sys.argv) != 2:
        raise SystemExit('usage: test_api_interp.py IPSD')
    with tempfile.TemporaryDirectory(prefix='ipsd-interp-') as tmp:
        d = Ipsd(sys.argv[1], tmp)
        try:
            run(d)
        finally:
            d.stop()
    print(f'{checks} checks, {fails} failed')
    return 1 if fails else 0


def run(d):
    # a uniform pixel, stored as the calibration of pixel (3, 4) of a 6 um sensor
    status, sensor = d.req('POST', '/api/sensors', {'model': 'INTERP', 'serial': 'T-1'})
    check(status == 201, 'sensor created', f'{status} {sensor}')
    flat = fit_upload(d, {'scan': scan_file(lambda x, y: 1.0), 'sensor_id': sensor['id'],
                          'pixel': {'col': 3, 'row': 4}})
    fid = flat['id']
    m = interp(d, f'/api/fits/{fid}/interp?r=8&n=60', 'uniform, r = 8')
    check(len(m['S']) == 3600 and all(abs(v - 1) <= LEAK_TOL for v in m['S']),
          'a uniform pixel\'s interpolated map is flat (S = 1)',
          f'{min(m["S"])}..{max(m["S"])}')
    best = flat['result']['recommended_r']
    m = interp(d, f'/api/fits/{fid}/interp', 'uniform, defaults')
    check(m['r'] == best and m['n'] == 100 and len(m['S']) == 10000,
          'default r is the recommended map and default n is 100', f'r {m["r"]}, n {m["n"]}')
    check_geometry(d, flat)

    # the calibration stored with it
    status, cal = d.req('GET', f"/api/sensors/{sensor['id']}/pixels/3/4/calibration")
    check(status == 200 and cal['fit_id'] == fid, 'the upload stored a calibration')
    r = cal['r']
    m = interp(d, f"/api/calibrations/{cal['id']}/interp?n={r}", 'calibration, n = r')
    check(m['calibration_id'] == cal['id'] and m['r'] == r and
          all(abs(a - b) <= 1e-12 for a, b in zip(m['S'], cal['S'])),
          'the calibration\'s map on the r x r grid is its S')
    m = interp(d, f"/api/calibrations/{cal['id']}/interp?n=33", 'calibration, n = 33')
    check(len(m['S']) == 33 * 33 and all(abs(v - 1) <= LEAK_TOL for v in m['S']),
          'the uniform calibration\'s interpolated map is flat')

    # a linear gradient along x: s = 0.7 + 0.6 x / pitch, mean 1 over the pixel
    grad = fit_upload(d, {'scan': scan_file(lambda x, y: 0.7 + 0.6 * x / PITCH)})
    gid = grad['id']
    for r in (4, 6, 8):  # r dividing GRID: the points of each sub-pixel are centred in it
        n = 5 * r
        m = interp(d, f'/api/fits/{gid}/interp?r={r}&n={n}', f'gradient, r = {r}')
        worst = max(abs(m['S'][j * n + i] - (0.7 + 0.6 * clamp((i + 0.5) / n, r)))
                    for j in range(n) for i in range(n))
        check(worst <= LEAK_TOL, f'r = {r}: the bicubic map of a linear gradient is that line '
              'along x (clamped outside the centres), the same in every row', f'worst {worst}')
    check_geometry(d, grad)

    # a sweep whose large r have too few points: their fits have no map
    few = [((i + 0.5) * PITCH / 6, (j + 0.5) * PITCH / 5) for j in range(5) for i in range(6)]
    sparse = fit_upload(d, {'scan': scan_file(lambda x, y: 1.0, few), 'r_max': 8})
    sid = sparse['id']
    nomap = [f['r'] for f in sparse['result']['fits'] if f['S'] is None]
    check(nomap and nomap[-1] == 8, 'the sparse scan has r without a map', str(nomap))

    def error(path, status, field, what):
        got, body = d.req('GET', path)
        e = body.get('error', {}) if isinstance(body, dict) else {}
        check(got == status and e.get('field') == field and e.get('code') and e.get('message'),
              f'{what}: {status}, field {field}', f'{got} {body}')

    error(f'/api/fits/{fid}/interp?n=0', 422, 'n', 'n = 0')
    error(f'/api/fits/{fid}/interp?n=501', 422, 'n', 'n = 501')
    error(f'/api/fits/{fid}/interp?n=ten', 400, 'n', 'n not an integer')
    error(f'/api/fits/{fid}/interp?r=0', 422, 'r', 'r = 0')
    error(f'/api/fits/{fid}/interp?r=9', 422, 'r', 'r outside the sweep 1..8')
    error(f'/api/fits/{fid}/interp?r=x', 400, 'r', 'r not an integer')
    error(f'/api/fits/{sid}/interp?r=8', 409, 'r', 'r whose fit has no map')
    error(f"/api/calibrations/{cal['id']}/interp?n=100000", 422, 'n', 'calibration n too large')
    error('/api/fits/9999/interp', 404, None, 'unknown fit')
    error('/api/calibrations/9999/interp', 404, None, 'unknown calibration')
    got, _ = d.req('POST', f'/api/fits/{fid}/interp', {})
    check(got == 405, 'POST on the interp route is 405', str(got))


if __name__ == '__main__':
    sys.exit(main())
