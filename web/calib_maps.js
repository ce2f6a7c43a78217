// calib_maps.js: the Pixel view's Plotly figures (charts.js), on the pixel's axes in µm with the
// pixel outlined:
//   - one calibration's map S (hover S ± S_err);
//   - two maps side by side on ONE colour scale with their difference A − B (a blue-white-red
//     scale symmetric about 0). Maps of the same r are subtracted sub-pixel by sub-pixel; maps of
//     different r (or a Wiener baseline, whose nodes are no r x r grid) are first resampled onto
//     a common n x n grid of cells over the pixel: each cell takes the value of the map's
//     sub-pixel (or Wiener node) nearest its centre (no interpolation: a sub-pixel's value holds
//     over its whole cell, the model's own assumption, paper eq. 2). n is the least common
//     multiple of the two r when it is at most MAX_COMMON, so both maps are exact on it. The
//     figure says which was done;
//   - the history of a pixel as small multiples: every map on one colour scale, newest first,
//     each titled with its map kind (recommended, shrunk, kriged) and grid.
// A "map source" is {label, S (row-major y then x), nx, ny, xs, ys (node centres, µm), cell
// (true: S_ij holds over sub-pixel cells; false: values at nodes), r (cells only)}.
import { DIVERGING, VIRIDIS, cellAxes, jointRange, outline, pixelFrame, plotFigure, rows,
    squareAxes } from './charts.js';

export const MAX_COMMON = 192; // cells per axis of a common grid at most (kriged maps of 24 and
                               // 28 cells meet exactly on 168)
const FALLBACK_N = 48;         // common grid with a map of nodes, at most
const FALLBACK_PER_CELL = 4;   // when the lcm is larger: 4 cells per cell of the finer map
const MAX_MULTIPLES = 24;     // maps in the history figure at most (the table lists them all)

const gcd = (a, b) => (b ? gcd(b, a % b) : a);
const centres = (n, w) => Array.from({ length: n }, (_, i) => (i + 0.5) * w / n);

const subTitle = (k, text) => ({ text, showarrow: false, xref: `x${k} domain`,
    yref: `y${k} domain`, x: 0.5, y: 1, xanchor: 'center', yanchor: 'bottom',
    font: { size: 12 } });

// The map source of a calibration (or of a fit's r x r map) over a pixel of width w.
export function cellSource(label, S, r, w, S_err) {
    return { label, S, S_err, nx: r, ny: r, r, xs: centres(r, w), ys: centres(r, w), cell: true };
}

// The map source of a fit's Wiener baseline (its nodes at x0_um + i step_um[0], docs/contracts.md).
export function wienerSource(label, wn) {
    return { label, S: wn.S, nx: wn.nx, ny: wn.ny, cell: false,
        xs: Array.from({ length: wn.nx }, (_, i) => wn.x0_um + i * wn.step_um[0]),
        ys: Array.from({ length: wn.ny }, (_, j) => wn.y0_um + j * wn.step_um[1]) };
}

// Index of the value of xs nearest x.
function nearest(xs, x) {
    let best = 0;
    for (let i = 1; i < xs.length; i++) if (Math.abs(xs[i] - x) < Math.abs(xs[best] - x)) best = i;
    return best;
}

// How two sources are compared: {n, same, how} — n x n cells; same: sub-pixel by sub-pixel.
export function commonGrid(a, b) {
    if (a.cell && b.cell && a.r === b.r) {
        return { n: a.r, same: true, how: `Both maps have r = ${a.r}: the difference is taken ` +
            'sub-pixel by sub-pixel, nothing resampled.' };
    }
    if (a.cell && b.cell) {
        const l = a.r * b.r / gcd(a.r, b.r);
        const n = l <= MAX_COMMON ? l
            : Math.min(MAX_COMMON, FALLBACK_PER_CELL * Math.max(a.r, b.r));
        return { n, same: false, how: `The maps have r = ${a.r} and r = ${b.r}: both resampled ` +
            `onto a common ${n} × ${n} grid (each cell takes the value of the sub-pixel under ` +
            `its centre${l <= MAX_COMMON ? '; exact, n is a multiple of both r' : ''}), then ` +
            'subtracted.' };
    }
    const n = Math.max(a.cell ? a.r : a.nx, b.cell ? b.r : b.nx, 1) <= FALLBACK_N
        ? Math.max(a.cell ? a.r : a.nx, b.cell ? b.r : b.nx) : FALLBACK_N;
    return { n, same: false, how: `Resampled onto a common ${n} × ${n} grid (each cell takes ` +
        'the value of the sub-pixel, or the Wiener node, nearest its centre), then subtracted.' };
}

// The values of source s on the common n x n grid of cells over [0, w]^2 (row-major).
export function resample(s, n, w) {
    const c = centres(n, w);
    const out = new Array(n * n);
    for (let j = 0; j < n; j++) {
        for (let i = 0; i < n; i++) {
            const ii = s.cell ? Math.min(s.nx - 1, Math.floor(c[i] / w * s.nx)) : nearest(s.xs, c[i]);
            const jj = s.cell ? Math.min(s.ny - 1, Math.floor(c[j] / w * s.ny)) : nearest(s.ys, c[j]);
            out[j * n + i] = s.S[jj * s.nx + ii];
        }
    }
    return out;
}

// A, B and A − B side by side: A and B on one colour scale, the difference on a symmetric one.
export function compareFigure(a, b, pitch) {
    const fr = pixelFrame(pitch);
    const g = commonGrid(a, b);
    const A = g.same ? a.S : resample(a, g.n, fr.w), B = g.same ? b.S : resample(b, g.n, fr.w);
    const D = A.map((v, k) => (Number.isFinite(v) && Number.isFinite(B[k]) ? v - B[k] : null));
    const [cmin, cmax] = jointRange(a.S, b.S);
    // the difference's scale: symmetric about 0; for identical maps a scale a hundredth of
    // theirs, so that 0 shows as white rather than as noise
    const lim = Math.max(0, ...D.filter(Number.isFinite).map(Math.abs)) ||
        (cmax - cmin) / 100 || 1e-3;
    const heat = (s, k) => ({ type: 'heatmap', name: s.label,
        ...(s.cell ? cellAxes(s.nx, fr.w, s.ny) : { x: s.xs, y: s.ys }),
        z: rows(s.S, s.nx, s.ny), coloraxis: 'coloraxis', xaxis: `x${k}`, yaxis: `y${k}`,
    hovertemplate: `x %{x:.3f}${fr.u}, y %{y:.3f}${fr.u}<br>S = %{z:.6g}<extra>${s.label}` +
        '</extra>' });
    const data = [heat(a, ''), heat(b, 2),
        { type: 'heatmap', name: 'A − B', ...cellAxes(g.n, fr.w), z: rows(D, g.n, g.n),
            coloraxis: 'coloraxis2', xaxis: 'x3', yaxis: 'y3',
            hovertemplate: `x %{x:.3f}${fr.u}, y %{y:.3f}${fr.u}<br>A − B = %{z:.4g}` +
                '<extra>difference</extra>' }];
    const cols = [[0, 0.26], [0.32, 0.58], [0.74, 1]];
    const range = [0, fr.w];
    const layout = { coloraxis: { colorscale: VIRIDIS, cmin, cmax, colorbar: { title:
        { text: 'S' }, thickness: 10, x: 0.595 } },
    coloraxis2: { colorscale: DIVERGING, cmin: -lim, cmax: lim, colorbar: { title:
        { text: 'A − B' }, thickness: 10 } },
    shapes: ['', 2, 3].map((k) => outline(fr, k)),
    annotations: [subTitle('', `A: ${a.label}`), subTitle(2, `B: ${b.label}`),
        subTitle(3, 'Difference A − B')] };
    ['', 2, 3].forEach((k, c) => Object.assign(layout, squareAxes(fr, k, cols[c], range)));
    const stacked = { height: 960, layout: {
        coloraxis: { ...layout.coloraxis, colorbar: { ...layout.coloraxis.colorbar, x: 1.02,
            y: 0.68, len: 0.62 } },
        coloraxis2: { ...layout.coloraxis2, colorbar: { ...layout.coloraxis2.colorbar, y: 0.125,
            len: 0.28 } } } };
    [[0.72, 0.97], [0.38, 0.63], [0, 0.25]].forEach((yd, c) => Object.assign(stacked.layout,
        squareAxes(fr, ['', 2, 3][c], [0, 1], range, yd)));
    const fig = plotFigure({ title: 'Two maps and their difference', testid: 'plot-compare',
        data, layout, height: 340, name: 'compare', stacked,
        note: `One colour scale for A and B. ${g.how}` });
    fig.dataset.grid = String(g.n);
    fig.dataset.resampled = String(!g.same);
    return { fig, diff: D, grid: g };
}

// One map S (hover S ± S_err) on the pixel's axes.
export function mapFigure(src, pitch, testid, title) {
    const fr = pixelFrame(pitch);
    return plotFigure({ title, testid, height: 340, name: testid,
        data: [{ type: 'heatmap', ...cellAxes(src.nx, fr.w, src.ny),
            z: rows(src.S, src.nx, src.ny), customdata: src.S_err ? rows(src.S_err, src.nx,
                src.ny) : undefined, colorscale: VIRIDIS,
            colorbar: { title: { text: 'S' }, thickness: 12 },
            hovertemplate: `x %{x:.3f}${fr.u}, y %{y:.3f}${fr.u}<br>S = %{z:.6g}` +
                `${src.S_err ? ' ± %{customdata:.2g}' : ''}<extra></extra>` }],
        layout: { ...squareAxes(fr, '', [0, 1], [0, fr.w]), shapes: [outline(fr)] } });
}

// The maps of a pixel's history (calibrations, newest first) as small multiples on one colour
// scale, cols per row (2 on a phone).
export function historyFigure(all, pitch, cols = 4) {
    const fr = pixelFrame(pitch);
    const items = all.slice(0, MAX_MULTIPLES);
    const [cmin, cmax] = jointRange(...items.map((c) => c.S));
    const grid = (nc) => {
        const nr = Math.ceil(items.length / nc), lay = {};
        items.forEach((c, k) => {
            const ax = k ? k + 1 : '', col = k % nc, row = Math.floor(k / nc);
            const gap = 0.08, w = (1 - gap * (nc - 1)) / nc, vgap = 0.1 / nr;
            const hgt = (1 - vgap * (nr - 1)) / nr;
            const x0 = col * (w + gap), y1 = 1 - row * (hgt + vgap);
            Object.assign(lay, squareAxes(fr, ax, [x0, x0 + w], [0, fr.w],
                [y1 - hgt, y1 - 0.09 / nr]));
            lay[`xaxis${ax}`].title = { text: '' };
            lay[`yaxis${ax}`].title = { text: '' };
        });
        return { lay, nr };
    };
    const big = grid(Math.min(cols, items.length)), small = grid(Math.min(2, items.length));
    const data = items.map((c, k) => ({ type: 'heatmap', name: `#${c.id}`,
        ...cellAxes(c.r, fr.w), z: rows(c.S, c.r, c.r),
        coloraxis: 'coloraxis', xaxis: `x${k ? k + 1 : ''}`, yaxis: `y${k ? k + 1 : ''}`,
        hovertemplate: `x %{x:.3f}${fr.u}, y %{y:.3f}${fr.u}<br>S = %{z:.6g}` +
            `<extra>#${c.id}</extra>` }));
    const date = (ms) => new Date(ms).toISOString().slice(0, 10);
    // two short lines, so that two columns of them fit a phone
    const titles = items.map((c, k) => ({ ...subTitle(k ? k + 1 : '', `#${c.id} · ` +
        `${c.map || 'recommended'} ${c.r}×${c.r}${c.current ? ' · current' : ''}<br>` +
        `${date(c.created_ms)}`), font: { size: 10 } }));
    const layout = { ...big.lay, annotations: titles, margin: { l: 40, r: 20, t: 40, b: 30 },
        coloraxis: { colorscale: VIRIDIS, cmin, cmax, colorbar: { title: { text: 'S' },
            thickness: 12 } },
        shapes: items.map((c, k) => outline(fr, k ? k + 1 : '')) };
    return plotFigure({ title: `The pixel's maps, newest first (one colour scale; axes in ` +
        `${fr.unit})${all.length > items.length ? `: the ${items.length} newest of ` +
            `${all.length}` : ''}`, testid: 'plot-history', data, layout, height: 40 + 230 * big.nr,
    name: 'history', stacked: { height: 40 + 220 * small.nr, layout: small.lay } });
}
