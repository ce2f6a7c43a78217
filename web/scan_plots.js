// scan_plots.js: the Scan view's Plotly.js figures (charts.js):
//   - the response raster of any pixel of the sub-frame (a scan file from
//     GET /api/scans/ID/pixels/DCOL/DROW?all=1) as a heat map over the spot positions, on the
//     pixel's axes in µm from its top-left corner (y downward, as in the API), the pixel
//     outlined, the colour linear or logarithmic, zoomed to the whole raster or to the pixel;
//     on the scan's whole raster grid, so a running scan shows its empty part too;
//   - the scan geometry (the paper's figure): the raster's spot positions over the sub-frame's
//     pixels, the pixel grid drawn, the pixel of interest and the pixel shown highlighted;
//   - the raster as CSV (x_um, y_um, value, sigma: the API's sigma_dn; the pitch in a header
//     comment).
// Figures are specs for charts.js showFigure: a running scan's are redrawn in place (Plotly.react,
// a stable uirevision) so the user's zoom and pan survive the refreshes.
// Clicking a spot (in either figure) names its point index (raster order, row by row from the
// top left: docs/api.md) to the caller, which shows that point's raw frames (scan_frames.js).
import { fmt, h } from './dom.js';
import { VIRIDIS, jointRange, outline, pixelFrame, rows, squareAxes } from './charts.js';

// Colour-blind safe marks (Okabe-Ito): stored spot positions, the pixel of interest, the pixel
// whose raster is shown.
const SPOT = '#d55e00', PENDING = '#b8bec9', POI = '#e69f00', SHOWN = '#0072b2';
const MAX_GEOMETRY_POINTS = 10000; // above this the geometry figure thins its spots (said so)

// The spot positions of scan's n x n raster on the axes of sub-frame pixel (dcol, drow), from
// that pixel's top-left corner: the raster is centred on the centre of the pixel of interest,
// whose top-left corner is at (-dcol, -drow) pitches (docs/api.md).
export function rasterAxis(scan, pitch, d) {
    const n = scan.raster.points_per_axis, step = scan.raster.step_um;
    const c = pitch / 2 - d * pitch - ((n - 1) / 2) * step;
    return Array.from({ length: n }, (_, k) => c + k * step);
}

// The grid {xs, ys, col(x), row(y), onGrid} the points of data sit on: the scan's raster
// (so a running scan shows its empty part, and a cell's point index is row * n + col), or, when
// the points are not on it, the distinct positions present (to 1e-6 µm).
function rasterGrid(data, scan) {
    const pitch = data.pitch_um;
    if (scan && scan.raster.points_per_axis <= 2000 && scan.raster.step_um > 0) {
        const xs = rasterAxis(scan, pitch, data.dcol ?? 0);
        const ys = rasterAxis(scan, pitch, data.drow ?? 0), step = scan.raster.step_um;
        const index = (a) => (v) => Math.round((v - a[0]) / step);
        const fits = (a) => (v) => {
            const k = (v - a[0]) / step;
            return Math.abs(k - Math.round(k)) < 1e-3 && Math.round(k) >= 0 &&
                Math.round(k) < a.length;
        };
        if (data.x_um.every(fits(xs)) && data.y_um.every(fits(ys))) {
            return { xs, ys, col: index(xs), row: index(ys), onGrid: true };
        }
    }
    const key = (v) => Math.round(v * 1e6);
    const axis = (a) => [...new Set(a.map(key))].sort((p, q) => p - q);
    const kx = axis(data.x_um), ky = axis(data.y_um);
    const ix = new Map(kx.map((v, i) => [v, i])), iy = new Map(ky.map((v, j) => [v, j]));
    return { xs: kx.map((v) => v / 1e6), ys: ky.map((v) => v / 1e6),
        col: (x) => ix.get(key(x)), row: (y) => iy.get(key(y)), onGrid: false };
}

// Log colour: the colour bar's ticks at 5 values between lo and hi (log10), labelled in DN.
function logTicks(lo, hi) {
    const t = Array.from({ length: 5 }, (_, k) => lo + (k / 4) * (hi - lo));
    return { tickmode: 'array', tickvals: t, ticktext: t.map((v) => fmt(10 ** v, 3)) };
}

// The response raster of a pixel (scan-file JSON) as a heat map over the spot positions, with
// the pixel's outline [0, pitch]^2: the figure's spec (charts.js plotFigure / showFigure), null
// while no point is stored. scan: the Scan (its raster grid); opt {log, zoom ('pixel' | 'all'),
// onPoint(index)}: logarithmic colour, the axes' range, a click on a measured cell. The user's
// zoom is kept across redraws of the same pixel and range (uirevision): the raster fills in.
export function rasterSpec(data, scan, opt = {}) {
    if (!data.x_um.length) return null;
    const fr = pixelFrame(data.pitch_um);
    const g = rasterGrid(data, scan), nx = g.xs.length, ny = g.ys.length;
    const values = new Array(nx * ny).fill(null);
    data.signal_dn.forEach((v, k) => {
        values[g.row(data.y_um[k]) * nx + g.col(data.x_um[k])] = Number.isFinite(v) ? v : null;
    });
    const log = !!opt.log;
    const shown = log ? values.map((v) => (v !== null && v > 0 ? Math.log10(v) : null)) : values;
    const [lo, hi] = jointRange(shown); // (not Math.min(...): a large raster overflows the stack)
    const bar = { title: { text: log ? 'DN (log)' : 'DN' }, thickness: 14,
        ...(log ? logTicks(lo, hi) : {}) };
    const dx = nx > 1 ? g.xs[1] - g.xs[0] : fr.w / 10, dy = ny > 1 ? g.ys[1] - g.ys[0] : dx;
    const whole = [Math.min(g.xs[0] - dx / 2, g.ys[0] - dy / 2, 0),
        Math.max(g.xs[nx - 1] + dx / 2, g.ys[ny - 1] + dy / 2, fr.w)];
    const pad = Math.max(dx, fr.w * 0.04);
    const range = opt.zoom === 'pixel' ? [-pad, fr.w + pad] : whole;
    const trace = { type: 'heatmap', x: g.xs, y: g.ys, z: rows(shown, nx, ny),
        colorscale: VIRIDIS, colorbar: bar, hoverongaps: false, xgap: 0, ygap: 0,
        hovertemplate: `x %{x:.3f}${fr.u}, y %{y:.3f}${fr.u}<br>signal ` +
            (log ? '%{customdata:.6g} DN' : '%{z:.6g} DN') + '<extra></extra>' };
    if (log) trace.customdata = rows(values, nx, ny);
    const pix = data.pixel ? `(${data.pixel.col}, ${data.pixel.row})` : '';
    const d = `${data.dcol ?? 0},${data.drow ?? 0}`, zoom = opt.zoom === 'pixel' ? 'pixel' : 'all';
    const pick = (ev) => {
        const p = ev.points?.[0];
        if (!p || !Array.isArray(p.pointIndex)) return;
        const [j, i] = p.pointIndex;
        if (values[j * nx + i] !== null) opt.onPoint(j * nx + i);
    };
    return {
        title: `Pixel ${pix}, offset (${data.dcol ?? 0}, ${data.drow ?? 0}) from the POI: mean ` +
            `signal (DN) against spot position, ${data.x_um.length} of ${nx * ny} points, ` +
            `${log ? 'log' : 'linear'} colour`,
        testid: 'raster-map', height: 400, name: `raster-${data.scan_id}-${data.dcol ?? 0}-` +
            `${data.drow ?? 0}`, data: [trace],
        layout: { ...squareAxes(fr, '', [0, 1], range), shapes: [{ ...outline(fr),
            line: { color: '#ffffff', width: 2, dash: 'dash' } }] },
        uirevision: `${data.scan_id} ${d} ${zoom}`,
        dataset: { zoom, colour: log ? 'log' : 'linear', pixel: d,
            points: String(data.x_um.length) },
        onClick: g.onGrid && opt.onPoint ? pick : null,
        note: `Axes from the pixel's top-left corner, y downward; the dashed square is the ` +
            `pixel. ${g.onGrid ? 'Click a spot for its raw frames.' : ''}`,
    };
}

// The scan's geometry (the paper's figure): the raster's spot positions (stored ones in colour,
// the rest grey) over the sub-frame's pixels, on axes in µm from the POI's top-left corner
// (y downward); the pixel grid, the scanned area (dashed), the pixel of interest (filled) and
// the pixel whose raster is shown (shown {dcol, drow}, outlined). onPoint(index) on a click.
// The figure's spec (charts.js showFigure): redrawn in place as the scan runs, the user's zoom
// kept.
export function geometrySpec(scan, pitch, shown, onPoint) {
    const fr = pixelFrame(pitch), w = fr.w, r = scan.raster;
    const n = r.points_per_axis, hs = Math.floor(r.sub_px / 2), ha = (r.area_px - 1) / 2;
    const axis = rasterAxis(scan, w, 0);
    const every = Math.max(1, Math.ceil(Math.sqrt((n * n) / MAX_GEOMETRY_POINTS)));
    const done = scan.points_done ?? 0;
    const pts = { x: [[], []], y: [[], []], k: [[], []] };
    for (let j = 0; j < n; j += every) {
        for (let i = 0; i < n; i += every) {
            const k = j * n + i, t = k < done ? 0 : 1;
            pts.x[t].push(axis[i]);
            pts.y[t].push(axis[j]);
            pts.k[t].push(k);
        }
    }
    const trace = (t, name, color) => ({ type: 'scatter', mode: 'markers', name, x: pts.x[t],
        y: pts.y[t], customdata: pts.k[t], marker: { color, size, line: { width: 0 } },
        hovertemplate: `point %{customdata}<br>x %{x:.3f}${fr.u}, y %{y:.3f}${fr.u}` +
            `<extra>${name}</extra>` });
    const lo = Math.min(-hs * w, -ha * w, axis[0]), hi = Math.max((hs + 1) * w, (ha + 1) * w,
        axis[n - 1]);
    const m = (hi - lo) * 0.02, range = [lo - m, hi + m];
    // a marker about half a drawn step wide on a graph some 300 px across
    const size = Math.max(2, Math.min(6, (150 * every * r.step_um) / (range[1] - range[0])));
    const data = [trace(0, 'stored', SPOT)];
    if (pts.x[1].length) data.push(trace(1, 'not yet measured', PENDING));
    const shapes = [];
    for (let k = -hs; k <= hs + 1; k++) { // the sub-frame's pixel grid
        const line = { color: '#8a93a6', width: 1 };
        shapes.push({ type: 'line', x0: k * w, x1: k * w, y0: -hs * w, y1: (hs + 1) * w, line,
            layer: 'below' });
        shapes.push({ type: 'line', y0: k * w, y1: k * w, x0: -hs * w, x1: (hs + 1) * w, line,
            layer: 'below' });
    }
    shapes.push({ type: 'rect', x0: 0, x1: w, y0: 0, y1: w, fillcolor: POI, opacity: 0.35,
        line: { width: 0 }, layer: 'below' });
    shapes.push({ type: 'rect', x0: -ha * w, x1: (ha + 1) * w, y0: -ha * w, y1: (ha + 1) * w,
        line: { color: '#333', width: 1.5, dash: 'dash' }, fillcolor: 'rgba(0,0,0,0)' });
    if (shown) {
        shapes.push({ type: 'rect', x0: shown.dcol * w, x1: (shown.dcol + 1) * w,
            y0: shown.drow * w, y1: (shown.drow + 1) * w, line: { color: SHOWN, width: 3 },
            fillcolor: 'rgba(0,0,0,0)' });
    }
    const layout = { ...squareAxes({ ...fr, xtitle: `x (${fr.unit}) from the POI's corner` },
        '', [0, 1], range), shapes, showlegend: true,
    legend: { orientation: 'h', x: 0, y: -0.18, yanchor: 'top' },
    margin: { l: 60, r: 20, t: 20, b: 90 } };
    return { title: `Scan geometry: ${n}×${n} spot positions over ` +
        `${r.area_px}×${r.area_px} pixels; the ${r.sub_px}×${r.sub_px} sub-frame`,
    testid: 'scan-geometry', data, layout, height: 440, name: `geometry-${scan.id}`,
    uirevision: `geometry-${scan.id}`, dataset: { points: String(n * n), done: String(done) },
    onClick: onPoint ? (ev) => {
        const p = ev.points?.[0];
        if (p && Number.isInteger(p.customdata) && p.customdata < done) onPoint(p.customdata);
    } : null,
    note: `Filled: the pixel of interest (${scan.poi.col}, ${scan.poi.row}); blue outline: ` +
        'the pixel whose raster is shown; dashed: the scanned area. ' +
        (every > 1 ? `Every ${every}th row and column of spots is drawn (${n * n} in all). `
            : '') + 'Click a spot for its raw frames.' };
}

// The raster (scan-file JSON) as CSV: x_um,y_um,value,sigma, one line per point in the API's
// order, numbers as JavaScript writes them (shortest round trip), a non-finite value empty;
// sigma is the API's sigma_dn (the automatic fit's noise model, named by sigma_model); header
// comments name the scan, the pixel, the pitch and what sigma is.
export function rasterCsv(d) {
    const num = (v) => (v === null || v === undefined || !Number.isFinite(v) ? '' : String(v));
    const sigma = d.sigma_dn || [];
    const lines = [
        `# ipsd scan ${d.scan_id}, pixel (${d.pixel?.col}, ${d.pixel?.row}) = offset ` +
            `(${d.dcol}, ${d.drow}) from the POI: mean signal against spot position`,
        `# pitch_um = ${d.pitch_um}`,
        '# x_um, y_um: spot centre from the pixel\'s top-left corner (y downward); value: mean ' +
            'signal (DN, bias included)',
        `# sigma: its uncertainty (DN) under the "${d.sigma_model ?? '?'}" noise model of the ` +
            `fit (ipsd's sigma_dn; "paper": eq. 5, with bias ${d.bias_dn} DN, read noise ` +
            `${d.read_noise_e} e-, gain ${d.gain_e_per_dn} e-/DN, ${d.frames} frames)`,
        'x_um,y_um,value,sigma',
    ];
    d.x_um.forEach((x, k) => {
        lines.push([num(x), num(d.y_um[k]), num(d.signal_dn[k]), num(sigma[k])].join(','));
    });
    return `${lines.join('\n')}\n`;
}

// A button that downloads text() as a file named filename() (a Blob made in the browser);
// text() null: nothing to download yet.
export function downloadButton(label, filename, type, text, testid) {
    return h('button', { type: 'button', class: 'small', 'data-testid': testid,
        onclick: () => {
            const body = text();
            if (body === null) return; // nothing loaded yet
            const url = URL.createObjectURL(new Blob([body], { type }));
            const a = h('a', { href: url, download: filename() });
            document.body.append(a);
            a.click();
            a.remove();
            setTimeout(() => URL.revokeObjectURL(url), 60000);
        } }, label);
}
