// interp.test.mjs: the dashboard's interpolated IPS map (web/interp.js) against analytic facts:
// a natural cubic spline's knot derivatives worked by hand, interpolation through the sub-pixel
// centres, exact reproduction of affine maps (bicubic) and bilinear ones (r = 2), constant
// extension outside the outermost centres. Node's own test runner, no dependencies:
//   node --test tests/web/interp.test.mjs
import assert from 'node:assert/strict';
import test from 'node:test';

import { interpolate, splineDerivatives } from '../../web/interp.js';

const close = (a, b, tol, what) => assert.ok(Math.abs(a - b) <= tol, `${what}: ${a} vs ${b}`);

test('natural spline through (0,0), (1,1), (2,0): slopes 3/2, 0, -3/2', () => {
    // by hand: (h0 + h1)/3 M1 = -2 gives M1 = -3; s'(x0) = 1 - (2*0 - 3)/6 = 3/2, s'(x1) = -1 +
    // 6/6 = 0, s'(x2) = -1 + (-3)/6 = -3/2
    const d = splineDerivatives([0, 1, 2], [0, 1, 0]);
    close(d[0], 1.5, 1e-15, 'd0');
    close(d[1], 0, 1e-15, 'd1');
    close(d[2], -1.5, 1e-15, 'd2');
});

test('the interpolated map passes through S at the sub-pixel centres', () => {
    for (const r of [1, 2, 3, 4, 5, 7, 10]) {
        const S = Array.from({ length: r * r }, (_, k) => 1 + 0.2 * Math.sin(1.7 * k + 0.3));
        const out = interpolate(S, r, r); // n = r: the output points are the centres
        S.forEach((v, k) => close(out[k], v, 1e-12, `r = ${r}, k = ${k}`));
    }
});

test('an affine map is reproduced exactly between the centres (bicubic, r = 6)', () => {
    const r = 6, n = 48, f = (x, y) => 0.9 + 0.25 * x - 0.4 * y;
    const c = (i) => (i + 0.5) / r;
    const S = [];
    for (let j = 0; j < r; j++) for (let i = 0; i < r; i++) S.push(f(c(i), c(j)));
    const out = interpolate(S, r, n);
    const clamp = (p) => Math.min(Math.max(p, c(0)), c(r - 1)); // constant extension outside
    for (let b = 0; b < n; b++) {
        for (let a = 0; a < n; a++) {
            close(out[b * n + a], f(clamp((a + 0.5) / n), clamp((b + 0.5) / n)), 1e-12,
                `point (${a}, ${b})`);
        }
    }
});

test('r = 2 is bilinear: a + bx + cy + dxy exactly, constant outside the centres', () => {
    const f = (x, y) => 1 + 0.5 * x - 0.3 * y + 0.8 * x * y;
    const S = [f(0.25, 0.25), f(0.75, 0.25), f(0.25, 0.75), f(0.75, 0.75)];
    const n = 20, out = interpolate(S, 2, n);
    for (let b = 0; b < n; b++) {
        for (let a = 0; a < n; a++) {
            const x = Math.min(Math.max((a + 0.5) / n, 0.25), 0.75);
            const y = Math.min(Math.max((b + 0.5) / n, 0.25), 0.75);
            close(out[b * n + a], f(x, y), 1e-14, `point (${a}, ${b})`);
        }
    }
});
