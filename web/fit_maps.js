// fit_maps.js: the Fit view's figures of one r x r map (Plotly.js, charts.js), all on the pixel's
// axes in micrometres from its top-left corner (pixel widths when the pitch is unknown) with the
// pixel outlined:
//   - the fitted S beside the Wiener-deconvolution baseline on ONE colour scale (so their
//     contrast compares), hover giving S ± S_err;
//   - the uncertainty S_err, and the resolution error S_res where the fit has one for that r;
//   - the interpolated map (GET /api/fits/{id}/interp, fit_interp_bicubic) as a 3-D surface, the
//     paper's own figure;
//   - the measured signal, the fitted model (fits[].model_dn) and the normalised residuals
//     (signal - model) / sigma at the spot positions, side by side on one spatial scale. The fit document has the residuals per point of its region in input order
//     (docs/contracts.md), not the positions: these come from the scan's pixel raster (GET
//     /api/scans/{id}/pixels/{dcol}/{drow}?all=1) selected by the fit's region as
//     fit_region_contains does (fit/region.c).
import { get } from './api.js';
import { failure, fill, fmt, h } from './dom.js';
import { DIVERGING, MAGMA, VIRIDIS, jointRange, outline, pixelFrame, plotFigure, rows,
    cellAxes, squareAxes, valueTable } from './charts.js';

export const INTERP_N = 100; // points per axis of the interpolated map
const EDGE_REL_TOL = 1e-6; // of the pitch: fit/region.c

// Subplot title k ('' or 2) above its plot area.
const subTitle = (k, text) => ({ text, showarrow: false, xref: `x${k} domain`,
    yref: `y${k} domain`, x: 0.5, y: 1, xanchor: 'center', yanchor: 'bottom',
    font: { size: 12 } });

// Sub-pixel centres of an r x r map on frame: (i + 1/2) w / r.
const centres = (r, w) => Array.from({ length: r }, (_, i) => (i + 0.5) * w / r);

// S (with S_err in the hover) and, when the fit has it, the Wiener baseline, side by side on one
// shared colour axis whose range spans both maps.
export function mapPairFigure(f, wiener, pitch) {
    const fr = pixelFrame(pitch);
    const r = f.r;
    const hasW = wiener && !wiener.error && Array.isArray(wiener.S);
    const [cmin, cmax] = jointRange(f.S, hasW ? wiener.S : null);
    const data = [{ type: 'heatmap', name: `S (r = ${r})`, ...cellAxes(r, fr.w),
        z: rows(f.S, r, r),
        customdata: f.S_err ? rows(f.S_err, r, r) : undefined, coloraxis: 'coloraxis',
        xaxis: 'x', yaxis: 'y', hovertemplate: `x %{x:.3f}${fr.u}, y %{y:.3f}${fr.u}<br>` +
            `S = %{z:.6g}${f.S_err ? ' ± %{customdata:.2g}' : ''}<extra>fitted S</extra>` }];
    const split = hasW ? [[0, 0.42], [0.58, 1]] : [[0, 1]];
    const layout = { ...squareAxes(fr, '', split[0], [0, fr.w]),
        coloraxis: { colorscale: VIRIDIS, cmin, cmax,
            colorbar: { title: { text: 'S (mean 1)' }, thickness: 14 } },
        shapes: [outline(fr, '')], annotations: [subTitle('', `Fitted S (${r}×${r})`)],
        margin: { l: 60, r: 20, t: 30, b: 50 } };
    let note = null, stacked = null;
    if (hasW) {
        const w = wiener;
        // Wiener nodes are positions in um (x0_um + i step_um[0]); they share the map's frame
        // when the pitch is known
        const wf = fr.um ? fr : { um: true, unit: 'µm', u: ' µm',
            xtitle: 'x (µm)', ytitle: 'y (µm), downward',
            w: Math.max(w.x0_um + w.nx * w.step_um[0], w.y0_um + w.ny * w.step_um[1]) };
        data.push({ type: 'heatmap', name: 'Wiener', coloraxis: 'coloraxis', xaxis: 'x2',
            yaxis: 'y2', x: Array.from({ length: w.nx }, (_, i) => w.x0_um + i * w.step_um[0]),
            y: Array.from({ length: w.ny }, (_, j) => w.y0_um + j * w.step_um[1]),
            z: rows(w.S, w.nx, w.ny), hovertemplate: `x %{x:.3f} µm, y %{y:.3f} µm<br>` +
                'S = %{z:.6g}<extra>Wiener</extra>' });
        Object.assign(layout, squareAxes(wf, 2, split[1], [0, wf.w]));
        // on a phone: S above the Wiener map, the colour bar beside both
        stacked = { height: 620, layout: { ...squareAxes(fr, '', [0, 1], [0, fr.w], [0.56, 0.96]),
            ...squareAxes(wf, 2, [0, 1], [0, wf.w], [0, 0.4]) } };
        layout.shapes.push(outline(wf, 2));
        layout.annotations.push(subTitle(2, `Wiener baseline (${w.nx}×${w.ny})`));
        note = 'One colour scale for both maps. The Wiener map is the deconvolved raster at ' +
            'its scan nodes inside the pixel.';
    } else {
        note = wiener?.error ? `Wiener baseline failed: ${wiener.error}`
            : 'No Wiener baseline was requested for this fit.';
    }
    const fig = plotFigure({ title: hasW ? 'Fitted sensitivity S beside the Wiener ' +
        'deconvolution baseline' : 'Fitted sensitivity S', testid: 'plot-maps', data, layout, note,
    height: 360, name: `map-r${r}`, stacked });
    if (r * r <= 400) fig.append(valueTable(f.S, r, r)); // the numbers, for keyboards and readers
    return fig;
}

// S_err, 1 sigma, on its own scale (testid: the graph's, another one for a second such figure).
export function errFigure(f, pitch, testid = 'plot-Serr') {
    const fr = pixelFrame(pitch), r = f.r;
    const fig = plotFigure({ title: 'Uncertainty S_err (1σ)', testid, height: 320,
        name: `S_err-r${r}`,
        data: [{ type: 'heatmap', ...cellAxes(r, fr.w), z: rows(f.S_err, r, r),
            colorscale: MAGMA,
            colorbar: { title: { text: 'S_err' }, thickness: 14 },
            hovertemplate: `x %{x:.3f}${fr.u}, y %{y:.3f}${fr.u}<br>S_err = %{z:.3g}` +
                '<extra></extra>' }],
        layout: { ...squareAxes(fr, '', [0, 1], [0, fr.w]), shapes: [outline(fr)] } });
    if (r * r <= 400) fig.append(valueTable(f.S_err, r, r));
    return fig;
}

// S_res, the resolution error of an r grid's sub-pixel values (fit/shrink.h: structure finer
// than the grid, which S_err does not count; add the two in quadrature), on its own scale.
export function resFigure(sRes, r, pitch, testid = 'plot-Sres') {
    const fr = pixelFrame(pitch);
    const fig = plotFigure({ title: 'Resolution error S_res (add in quadrature to S_err)',
        testid, height: 320, name: `S_res-r${r}`,
        data: [{ type: 'heatmap', ...cellAxes(r, fr.w), z: rows(sRes, r, r),
            colorscale: MAGMA,
            colorbar: { title: { text: 'S_res' }, thickness: 14 },
            hovertemplate: `x %{x:.3f}${fr.u}, y %{y:.3f}${fr.u}<br>S_res = %{z:.3g}` +
                '<extra></extra>' }],
        layout: { ...squareAxes(fr, '', [0, 1], [0, fr.w]), shapes: [outline(fr)] } });
    if (r * r <= 400) fig.append(valueTable(sRes, r, r));
    return fig;
}

// The interpolated map from the server (interpPath: the route with its ?r=) as a 3-D surface,
// "loading" until it arrives.
export function surfaceFigure(interpPath, pitch) {
    const box = h('figure', { class: 'pfig', dataset: { state: 'loading' } },
        h('figcaption', {}, 'Interpolated map (3-D)'), h('p', { class: 'muted' }, 'Loading…'));
    const sep = interpPath.includes('?') ? '&' : '?';
    get(`${interpPath}${sep}n=${INTERP_N}`).then((m) => {
        const fr = pixelFrame(pitch);
        // output point k of n sits at (k + 1/2) / n of the pitch (docs/api.md)
        const xs = centres(m.n, fr.w);
        const axis = (t) => ({ title: { text: t } });
        const fig = plotFigure({ title: `Interpolated map, ${m.n}×${m.n} (${m.method}), as a ` +
            'surface', testid: 'plot-surface', height: 420, name: `interp-r${m.r}`,
        data: [{ type: 'surface', x: xs, y: xs, z: rows(m.S, m.n, m.n), colorscale: VIRIDIS,
            colorbar: { title: { text: 'S' }, thickness: 14 },
            hovertemplate: `x %{x:.3f}${fr.u}, y %{y:.3f}${fr.u}<br>S ≈ %{z:.6g}` +
                '<extra></extra>' }],
        layout: { margin: { l: 0, r: 0, t: 10, b: 0 },
            scene: { xaxis: axis(`x (${fr.unit})`), yaxis: { ...axis(`y (${fr.unit}, down)`),
                autorange: 'reversed' }, zaxis: axis('S'), aspectmode: 'manual',
            aspectratio: { x: 1, y: 1, z: 0.6 } } },
        note: 'Drag to turn, scroll to zoom. y grows downward, as on the heat maps.' });
        fig.dataset.state = 'ready';
        box.replaceWith(fig);
    }).catch((err) => {
        box.dataset.state = 'failed';
        fill(box, h('figcaption', {}, 'Interpolated map'), failure(err));
    });
    return box;
}

// 1 when a spot at (x, y) belongs to the fit's region (fit_region_contains, fit/region.c).
function inRegion(res, p, x, y) {
    const eps = EDGE_REL_TOL * p;
    if (!Number.isFinite(x) || !Number.isFinite(y)) return true;
    if (res.region === 'all') return true;
    if (res.region === 'margin') {
        const lo = -res.margin_um - eps, hi = p + res.margin_um + eps;
        return x >= lo && x <= hi && y >= lo && y <= hi;
    }
    return x > eps && x < p - eps && y > eps && y < p - eps;
}

// The fit's points: {x, y, signal, pitch} of the points its residuals belong to, in their order,
// from the scan's pixel raster; rejects with a reason when they cannot be known.
export async function fitPoints(fit) {
    const res = fit.result || {};
    if (!fit.scan_id) throw new Error('the fit is of an uploaded scan file: its spot positions ' +
        'are not stored');
    const raster = await get(`/api/scans/${fit.scan_id}/pixels/${fit.dcol}/${fit.drow}?all=1`);
    const p = raster.pitch_um, out = { x: [], y: [], signal: [], pitch: p };
    raster.x_um.forEach((x, k) => {
        if (!inRegion(res, p, x, raster.y_um[k])) return;
        out.x.push(x);
        out.y.push(raster.y_um[k]);
        out.signal.push(raster.signal_dn[k]);
    });
    if (res.n_points !== undefined && out.x.length !== res.n_points) {
        throw new Error(`the scan's raster has ${out.x.length} points in the fit's region ` +
            `(${res.region}), the fit ${res.n_points}`);
    }
    return out;
}

// The measured signal, the fitted model at the same points (fits[].model_dn, DN, on the
// signal's colour scale so that the two compare) and the normalised residuals (data - model) / σ
// of map f, side by side on one spatial scale (the map's µm axes, one range for all three, the
// pixel outlined). pts: fitPoints' answer. A fit stored before model_dn existed shows the signal
// and the residuals only (σ is not in the document, so the model cannot be recovered from them).
export function residualFigure(f, pts) {
    const fr = pixelFrame(pts.pitch);
    const resid = f.residuals || [];
    const model = Array.isArray(f.model_dn) ? f.model_dn : null;
    const keep = resid.map((v, k) => k).filter((k) => Number.isFinite(resid[k]));
    // a marker about one raster step wide: the step from the sorted distinct x positions
    const ux = [...new Set(pts.x.filter(Number.isFinite).map((v) => v.toFixed(6)))]
        .map(Number).sort((a, b) => a - b);
    const steps = ux.slice(1).map((v, k) => v - ux[k]).filter((d) => d > 0);
    const step = steps.length ? steps.sort((a, b) => a - b)[steps.length >> 1] : fr.w / 10;
    const [lo0, hi0] = jointRange(pts.x, pts.y, [0, fr.w]);
    const range = [lo0 - step / 2, hi0 + step / 2];
    const panels = model ? 3 : 2;
    const size = Math.min(22, Math.max(3, (panels === 3 ? 170 : 230) * step /
        (range[1] - range[0])));
    const marker = (color, axis) => ({ color, coloraxis: axis, symbol: 'square', size,
        line: { width: 0 } });
    const lim = Math.max(3, ...keep.map((k) => Math.abs(resid[k])));
    const mk = model ? keep.filter((k) => Number.isFinite(model[k])) : [];
    // signal and model on one DN scale spanning both
    const [dmin, dmax] = jointRange(pts.signal, mk.map((k) => model[k]));
    const ax = ['', 2, 3].slice(0, panels);
    const resAx = ax[panels - 1];
    const data = [
        { type: 'scatter', mode: 'markers', name: 'signal', x: pts.x, y: pts.y,
            marker: marker(pts.signal, 'coloraxis'), xaxis: 'x', yaxis: 'y',
            hovertemplate: 'x %{x:.3f} µm, y %{y:.3f} µm<br>signal %{marker.color:.6g} DN' +
                '<extra></extra>' },
        model ? { type: 'scatter', mode: 'markers', name: 'model', x: mk.map((k) => pts.x[k]),
            y: mk.map((k) => pts.y[k]), customdata: mk,
            marker: marker(mk.map((k) => model[k]), 'coloraxis'), xaxis: 'x2', yaxis: 'y2',
            hovertemplate: 'x %{x:.3f} µm, y %{y:.3f} µm<br>model %{marker.color:.6g} DN' +
                '<extra>point %{customdata}</extra>' } : null,
        { type: 'scatter', mode: 'markers', name: 'residual', x: keep.map((k) => pts.x[k]),
            y: keep.map((k) => pts.y[k]), customdata: keep,
            marker: marker(keep.map((k) => resid[k]), 'coloraxis2'), xaxis: `x${resAx}`,
            yaxis: `y${resAx}`, hovertemplate: 'x %{x:.3f} µm, y %{y:.3f} µm<br>(data − model)' +
                ' / σ = %{marker.color:.3f}<extra>point %{customdata}</extra>' },
    ].filter(Boolean);
    // side by side: three columns with the DN colour bar between the model and the residuals
    const cols = panels === 3 ? [[0, 0.26], [0.32, 0.58], [0.74, 1]] : [[0, 0.38], [0.62, 1]];
    const layout = { showlegend: false,
        coloraxis: { colorscale: VIRIDIS, cmin: dmin, cmax: dmax, colorbar: { title:
            { text: 'DN' }, thickness: 10, x: panels === 3 ? 0.595 : 0.4 } },
        coloraxis2: { colorscale: DIVERGING, cmin: -lim, cmax: lim,
            colorbar: { title: { text: 'σ' }, thickness: 10 } },
        shapes: ax.map((k) => outline(fr, k)),
        annotations: [subTitle('', 'Measured signal'),
            model ? subTitle(2, 'Fitted model') : null,
            subTitle(resAx, '(data − model) / σ')].filter(Boolean) };
    ax.forEach((k, c) => Object.assign(layout, squareAxes(fr, k, cols[c], range)));
    // on a phone: one above the other, each colour bar beside its plots
    const rowsY = panels === 3 ? [[0.72, 0.97], [0.38, 0.63], [0, 0.25]] : [[0.56, 0.96], [0, 0.4]];
    const stackedLayout = {
        coloraxis: { ...layout.coloraxis, colorbar: { ...layout.coloraxis.colorbar, x: 1.02,
            y: panels === 3 ? 0.68 : 0.76, len: panels === 3 ? 0.62 : 0.42 } },
        coloraxis2: { ...layout.coloraxis2, colorbar: { ...layout.coloraxis2.colorbar,
            y: panels === 3 ? 0.125 : 0.2, len: panels === 3 ? 0.28 : 0.42 } } };
    ax.forEach((k, c) => Object.assign(stackedLayout, squareAxes(fr, k, [0, 1], range,
        rowsY[c])));
    const n = resid.length, out = n - keep.length;
    const chi = keep.reduce((a, k) => a + resid[k] * resid[k], 0);
    return plotFigure({ title: `Measured signal, ${model ? 'fitted model ' : ''}and normalised ` +
        `residuals (r = ${f.r})`, testid: 'plot-resid', data, layout, height: 340,
    name: `residuals-r${f.r}`, stacked: { height: panels === 3 ? 960 : 640,
        layout: stackedLayout },
    note: `${keep.length} points fitted${out ? `, ${out} left out` : ''}; Σ residual² = ` +
        `${fmt(chi, 5)} (the χ²). ${model ? 'Signal and model share one colour scale (DN). '
        : 'This fit was stored before the model values were kept: no model panel. '}` +
        'Residuals should scatter about 0 without a pattern; a pattern at the pixel edges says ' +
        'the model misses something there.' });
}
