// interp.js: the paper's "interpolated IPS map", computed in the browser from the r x r map S the
// same way as the server's fit/interp.c (GSL gsl_spline2d): sub-pixel i has its centre at
// (i + 1/2) / r of the pitch; the map is sampled on an n x n grid at (k + 1/2) / n, points
// outside the outermost centres clamped onto them. r >= 4: bicubic (GSL's gsl_interp2d_bicubic:
// a bicubic Hermite patch per cell whose corner derivatives come from natural cubic splines
// through the rows, columns and x-derivatives); r = 2, 3: bilinear; r = 1: constant.
// Hand-written because the dashboard has no dependencies; it is a few lines of standard algebra.

// The derivative at each knot of the natural cubic spline through (x[i], y[i]).
export function splineDerivatives(x, y) {
    const n = x.length;
    const d = new Float64Array(n);
    if (n < 2) return d;
    if (n === 2) {
        d[0] = d[1] = (y[1] - y[0]) / (x[1] - x[0]);
        return d;
    }
    // second derivatives M (M[0] = M[n-1] = 0) from the tridiagonal system, Thomas algorithm
    const M = new Float64Array(n), c = new Float64Array(n), r = new Float64Array(n);
    for (let i = 1; i < n - 1; i++) {
        const h0 = x[i] - x[i - 1], h1 = x[i + 1] - x[i];
        const a = h0 / 6, b = (h0 + h1) / 3, cc = h1 / 6;
        const rhs = (y[i + 1] - y[i]) / h1 - (y[i] - y[i - 1]) / h0;
        const m = b - a * c[i - 1];
        c[i] = cc / m;
        r[i] = (rhs - a * r[i - 1]) / m;
    }
    for (let i = n - 2; i >= 1; i--) M[i] = r[i] - c[i] * M[i + 1];
    for (let i = 0; i < n - 1; i++) {
        const hh = x[i + 1] - x[i];
        d[i] = (y[i + 1] - y[i]) / hh - hh * (2 * M[i] + M[i + 1]) / 6;
    }
    const hh = x[n - 1] - x[n - 2];
    d[n - 1] = (y[n - 1] - y[n - 2]) / hh + hh * (M[n - 2] + 2 * M[n - 1]) / 6;
    return d;
}

// Cubic Hermite basis on [0, 1]: value at 0, value at 1, slope at 0, slope at 1.
function hermite(t) {
    const t2 = t * t, t3 = t2 * t;
    return [2 * t3 - 3 * t2 + 1, -2 * t3 + 3 * t2, t3 - 2 * t2 + t, t3 - t2];
}

// The cell index k with c[k] <= p <= c[k + 1].
function cell(c, p) {
    let k = 0;
    while (k < c.length - 2 && p > c[k + 1]) k++;
    return k;
}

// map: r*r values, row-major y then x. Returns n*n values (Float64Array), row-major y then x.
export function interpolate(map, r, n) {
    const out = new Float64Array(n * n);
    if (r === 1) return out.fill(map[0]);
    const c = Array.from({ length: r }, (_, i) => (i + 0.5) / r);
    const p = Array.from({ length: n }, (_, k) => Math.min(Math.max((k + 0.5) / n, c[0]),
        c[r - 1]));
    const at = (i, j) => map[j * r + i];
    let zx = null, zy = null, zxy = null;
    if (r >= 4) {
        zx = new Float64Array(r * r);
        zy = new Float64Array(r * r);
        zxy = new Float64Array(r * r);
        for (let j = 0; j < r; j++) {
            const d = splineDerivatives(c, c.map((_, i) => at(i, j)));
            for (let i = 0; i < r; i++) zx[j * r + i] = d[i];
        }
        for (let i = 0; i < r; i++) {
            const d = splineDerivatives(c, c.map((_, j) => at(i, j)));
            for (let j = 0; j < r; j++) zy[j * r + i] = d[j];
        }
        for (let j = 0; j < r; j++) { // GSL: the x-derivative of the y-derivatives
            const d = splineDerivatives(c, c.map((_, i) => zy[j * r + i]));
            for (let i = 0; i < r; i++) zxy[j * r + i] = d[i];
        }
    }
    for (let b = 0; b < n; b++) {
        const yi = cell(c, p[b]), dy = c[yi + 1] - c[yi], u = (p[b] - c[yi]) / dy;
        for (let a = 0; a < n; a++) {
            const xi = cell(c, p[a]), dx = c[xi + 1] - c[xi], t = (p[a] - c[xi]) / dx;
            let v = 0;
            if (!zx) { // bilinear
                v = (1 - t) * (1 - u) * at(xi, yi) + t * (1 - u) * at(xi + 1, yi) +
                    (1 - t) * u * at(xi, yi + 1) + t * u * at(xi + 1, yi + 1);
            } else {
                const ht = hermite(t), hu = hermite(u);
                for (let q = 0; q < 2; q++) {
                    for (let s = 0; s < 2; s++) {
                        const k = (yi + s) * r + (xi + q);
                        v += map[k] * ht[q] * hu[s] + zx[k] * dx * ht[2 + q] * hu[s] +
                            zy[k] * dy * ht[q] * hu[2 + s] +
                            zxy[k] * dx * dy * ht[2 + q] * hu[2 + s];
                    }
                }
            }
            out[b * n + a] = v;
        }
    }
    return out;
}
