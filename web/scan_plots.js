// scan_plots.js: the picture of a scan: the response raster of one pixel (a scan file from
// GET /api/scans/ID/pixels/DCOL/DROW?all=1) as a heatmap over the spot positions, with the
// pixel's outline; on the scan's whole raster grid, so a running scan shows its empty part too.
import { fmt, h } from './dom.js';
import { heatmap } from './plots.js';

// The response raster of a pixel (scan-file JSON) as a heatmap over the spot positions, with the
// pixel's outline [0, pitch] x [0, pitch]. grid {n, step}: the scan's whole raster (n x n points
// centred on the pixel), so a running scan shows its empty part too; without it (or when the
// points are not on it) the grid is the distinct positions present.
export function rasterFigure(data, grid) {
    if (!data.x_um.length) return h('p', { class: 'muted' }, 'No points stored yet.');
    const pitch = data.pitch_um;
    const axes = (grid && onGrid(data, grid, pitch)) || distinctAxes(data);
    const { xs, ys } = axes, nx = xs.length, ny = ys.length;
    const values = new Float64Array(nx * ny).fill(NaN);
    data.signal_dn.forEach((v, k) => {
        values[axes.row(data.y_um[k]) * nx + axes.col(data.x_um[k])] = v;
    });
    const x0 = xs[0], y0 = ys[0];
    const dx = nx > 1 ? (xs[nx - 1] - x0) / (nx - 1) : 1;
    const dy = ny > 1 ? (ys[ny - 1] - y0) / (ny - 1) : 1;
    return heatmap({
        values, nx, ny, size: 300, unit: 'DN', testid: 'raster-map',
        title: `Pixel (${data.pixel.col}, ${data.pixel.row}): mean signal (DN) against spot ` +
            `position, ${data.x_um.length} of ${nx * ny} points`,
        describe: (i, j, v) => `spot at x = ${fmt(xs[i])} µm, y = ${fmt(ys[j])} µm: ` +
            (Number.isFinite(v) ? `${fmt(v, 6)} DN` : 'not measured (yet)'),
        outline: (ctx, w, hh) => { // the pixel's edges, in canvas units
            const X = (x) => (x - (x0 - dx / 2)) / (nx * dx) * w;
            const Y = (y) => (y - (y0 - dy / 2)) / (ny * dy) * hh;
            ctx.strokeStyle = '#ffffff';
            ctx.lineWidth = Math.max(1, w / 300);
            ctx.setLineDash([4, 3]);
            ctx.strokeRect(X(0), Y(0), X(pitch) - X(0), Y(pitch) - Y(0));
        },
    });
}

// The axes {xs, ys, col(x), row(y)} of the scan's n x n raster centred on the pixel, or null
// when the data's points are not on it.
function onGrid(data, grid, pitch) {
    const { n, step } = grid;
    if (!(n >= 1 && step > 0) || n > 2000) return null;
    const c = pitch / 2 - ((n - 1) / 2) * step;
    const axis = Array.from({ length: n }, (_, k) => c + k * step);
    const index = (v) => Math.round((v - c) / step);
    const fits = (v) => Math.abs((v - c) / step - index(v)) < 1e-3 && index(v) >= 0 &&
        index(v) < n;
    if (!data.x_um.every(fits) || !data.y_um.every(fits)) return null;
    return { xs: axis, ys: axis, col: index, row: index };
}

// The axes made of the distinct positions present (to 1e-6 um).
function distinctAxes(data) {
    const key = (v) => Math.round(v * 1e6);
    const axis = (a) => [...new Set(a.map(key))].sort((p, q) => p - q);
    const kx = axis(data.x_um), ky = axis(data.y_um);
    const ix = new Map(kx.map((v, i) => [v, i])), iy = new Map(ky.map((v, j) => [v, j]));
    return { xs: kx.map((v) => v / 1e6), ys: ky.map((v) => v / 1e6),
        col: (x) => ix.get(key(x)), row: (y) => iy.get(key(y)) };
}
