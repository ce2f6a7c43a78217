// charts.js: the dashboard's Plotly.js figures: heat maps on a pixel's axes in
// micrometres with the pixel outline drawn, a 3-D surface, and values at spot positions; each
// with hover values, zoom and Plotly's mode bar (PNG export, plus an SVG button). Plotly is the
// npm package plotly.js-dist-min pinned by web/package-lock.json, installed by `npm ci --prefix
// web` (scripts/run.sh, scripts/test.sh) and loaded by index.html as window.Plotly before the
// modules, from ipsd itself (no CDN: labs are often offline). Without it every figure says how
// to install it (the rest of the page works). docs/web.md.
import { fmt, h } from './dom.js';

// Colour scales, perceptually uniform and colour-blind safe: viridis for maps (Plotly's own),
// magma (matplotlib's, 9 stops) for uncertainties, and blue-white-red (ColorBrewer RdBu, safe
// for the common colour blindnesses) centred on 0 for signed residuals.
export const VIRIDIS = 'Viridis';
const stops = (cs) => cs.map((c, k) => [k / (cs.length - 1), c]);
export const MAGMA = stops(['#000004', '#1c1044', '#4f127b', '#812581', '#b5367a', '#e55964',
    '#fb8761', '#fec287', '#fcfdbf']);
export const DIVERGING = stops(['#2166ac', '#67a9cf', '#d1e5f0', '#f7f7f7', '#fddbc7', '#ef8a62',
    '#b2182b']);

export const plotlyReady = () => typeof window.Plotly?.newPlot === 'function';

// The message a figure shows when the bundle did not load.
function missing() {
    return h('p', { class: 'warn plot-missing', 'data-testid': 'plotly-missing' },
        'The plotting library (Plotly.js) is not installed, so this figure cannot be drawn: run ',
        h('code', {}, 'npm ci --prefix web'), ' in the ipsd source directory (scripts/run.sh does)' +
        ' and reload the page.');
}

// Plotly's mode bar with an SVG download next to its PNG one (camera icon).
function config(name) {
    const P = window.Plotly;
    return {
        responsive: true, displaylogo: false, displayModeBar: true,
        toImageButtonOptions: { format: 'png', filename: name, scale: 2 },
        modeBarButtonsToAdd: [{ name: 'Download plot as SVG', icon: P.Icons.disk,
            click: (gd) => P.downloadImage(gd, { format: 'svg', filename: name }) }],
    };
}

// A figure holding one Plotly graph: title, the graph's testid, and data + layout (drawn once the
// div is in the document, so that it takes its container's width). The graph div carries
// Plotly's own `data` and `layout` (what the browser test reads).
// stacked: an optional second layout, and its height, for a narrow graph (a phone): side-by-side
// subplots one above the other.
// Live figures (a running scan's): uirevision (layout.uirevision) lets updateFigure redraw the
// graph in place keeping the user's zoom and pan while it stays the same; dataset: attributes set
// on the graph div with each drawing; onClick(plotly_click event): bound once, the latest spec's
// called.
export function plotFigure(spec) {
    const { title, testid, height = 340, note } = spec;
    const graph = h('div', { class: 'pgraph', 'data-testid': testid });
    graph.style.height = `${height}px`;
    const fig = h('figure', { class: 'pfig' }, h('figcaption', {}, title),
        plotlyReady() ? graph : missing(), h('p', { class: 'muted small', hidden: !note }, note));
    if (!plotlyReady()) return fig;
    graph._spec = spec;
    Object.assign(graph.dataset, spec.dataset || {});
    let tries = 0;
    const draw = () => {
        if (!graph.isConnected) {
            if (++tries < 600) requestAnimationFrame(draw);
            return;
        }
        if (spec.stacked && graph.clientWidth < 520) {
            graph.style.height = `${spec.stacked.height}px`;
            graph.dataset.stacked = 'true';
        }
        paint(graph);
    };
    requestAnimationFrame(draw);
    return fig;
}

// The layout graph draws spec with: ours, the caller's, the stacked one when stacked.
function layoutOf(graph, spec) {
    const lay = { autosize: true, margin: { l: 60, r: 20, t: 30, b: 50 }, font: { size: 11 },
        ...spec.layout };
    if (graph.dataset.stacked === 'true') Object.assign(lay, spec.stacked.layout);
    if (spec.uirevision !== undefined) lay.uirevision = spec.uirevision;
    return lay;
}

// Draws graph's latest spec: Plotly.newPlot the first time, then Plotly.react (in place: what
// the user zoomed stays while layout.uirevision does). One drawing at a time; a spec given
// meanwhile is drawn next. data-state is "ready" once drawn; data-updates counts the redraws
// after the first (the browser test waits on it). Not while the user drags on the graph (Plotly's
// gd._dragging: a redraw would drop the zoom box or pan under the pointer): just after.
function paint(graph) {
    if (graph._busy) {
        graph._again = true;
        return;
    }
    if (graph._dragging) {
        if (!graph._waiting) {
            graph._waiting = true;
            const later = () => {
                if (graph._dragging) return requestAnimationFrame(later);
                graph._waiting = false;
                return paint(graph);
            };
            requestAnimationFrame(later);
        }
        return;
    }
    graph._busy = true;
    // a new uirevision (the caller's new axes: another pixel, another zoom) is drawn afresh:
    // react would keep some of the old axes (constrain: 'domain' writes its domain into the
    // layout it was given)
    const P = window.Plotly, spec = graph._spec;
    const first = !graph._drawn || graph._rev !== spec.uirevision;
    graph._rev = spec.uirevision;
    // one config per graph: react redraws from scratch (dropping the user's zoom) when the
    // config differs, and a new one would (its SVG button's function is new)
    graph._config ??= config(spec.name || spec.testid);
    const draw = first ? P.newPlot : P.react;
    draw(graph, spec.data, layoutOf(graph, spec), graph._config).then(() => {
        graph._busy = false;
        if (first) { // (again after a newPlot, which may have dropped it; never twice)
            graph._onClick ??= (ev) => graph._spec.onClick?.(ev);
            graph.removeListener('plotly_click', graph._onClick);
            graph.on('plotly_click', graph._onClick);
        }
        if (graph._drawn) graph.dataset.updates = String(Number(graph.dataset.updates || 0) + 1);
        graph._drawn = true;
        if (graph._again) {
            graph._again = false;
            paint(graph);
            return;
        }
        graph.dataset.state = 'ready';
    });
}

// Updates figure fig (plotFigure's answer, in the document) to spec in place: caption, note,
// the graph's attributes and its Plotly graph (Plotly.react). Returns false when fig is not such
// a figure with spec's testid (the caller then draws a new one).
export function updateFigure(fig, spec) {
    const graph = fig?.querySelector?.(':scope > .pgraph');
    if (!graph || !graph._spec || !fig.isConnected || graph.dataset.testid !== spec.testid) {
        return false;
    }
    fig.querySelector(':scope > figcaption').textContent = spec.title;
    const note = fig.querySelector(':scope > p.muted');
    if (note) {
        note.textContent = spec.note || '';
        note.hidden = !spec.note;
    }
    graph._spec = spec;
    if (!graph._drawn && !graph._busy) { // its first drawing has not started: it draws this
        Object.assign(graph.dataset, spec.dataset || {});
        return true;
    }
    graph.dataset.state = 'updating';
    Object.assign(graph.dataset, spec.dataset || {});
    paint(graph);
    return true;
}

// Shows spec in slot: the figure already there updated in place (updateFigure) when it is the
// same graph, else a new figure (the old ones purged). Returns the figure.
export function showFigure(slot, spec) {
    const old = slot.querySelector(':scope > figure.pfig');
    if (old && updateFigure(old, spec)) return old;
    purgeIn(slot);
    const fig = plotFigure(spec);
    slot.replaceChildren(fig);
    return fig;
}

// Frees the Plotly graphs under el (their resize listeners) before el's content is replaced.
export function purgeIn(el) {
    if (!plotlyReady()) return;
    for (const g of el.querySelectorAll('.js-plotly-plot')) window.Plotly.purge(g);
}

// The axes of a pixel: x to the right and y downward from its top-left corner (docs/contracts.md
// "Coordinates"), in micrometres when the pitch is known, else in pixel widths (said on the axis;
// the figures' section says where the origin is: short titles fit a phone).
export function pixelFrame(pitch) {
    const um = Number.isFinite(pitch) && pitch > 0;
    const unit = um ? 'µm' : 'pixel widths; pitch unknown';
    return {
        w: um ? pitch : 1, um, unit, u: um ? ' µm' : ' px',
        xtitle: `x (${unit})`, ytitle: `y (${unit}), downward`,
    };
}

// Axis pair for a subplot k ('' or 2, 3, ...) spanning range [lo, hi] on both axes, y downward,
// one unit the same length on both; a subplot right of another (k not '') has a short y title,
// which would otherwise run into its neighbour.
export function squareAxes(frame, k, domain, range, ydomain = [0, 1]) {
    const x = `xaxis${k}`, y = `yaxis${k}`;
    return {
        [x]: { title: { text: frame.xtitle }, domain, range, zeroline: false, constrain: 'domain',
            anchor: `y${k}` },
        [y]: { title: { text: k ? `y (${frame.unit})` : frame.ytitle }, range: [range[1], range[0]],
            domain: ydomain, zeroline: false,
            scaleanchor: `x${k}`, constrain: 'domain', anchor: `x${k}` },
    };
}

// The pixel's outline [0, w]^2 on subplot k.
export function outline(frame, k = '') {
    return { type: 'rect', xref: `x${k}`, yref: `y${k}`, x0: 0, x1: frame.w, y0: 0, y1: frame.w,
        line: { color: '#111', width: 1.5 }, fillcolor: 'rgba(0,0,0,0)', layer: 'above' };
}

// A heatmap's cell positions: the n centres over [0, w] on both axes; one cell (r = 1) as x0 / dx
// instead, since Plotly cannot infer a cell's size from one centre (it would draw a 1-unit square).
export function cellAxes(n, w, ny = n) {
    const c = (m) => Array.from({ length: m }, (_, i) => (i + 0.5) * w / m);
    return { ...(n > 1 ? { x: c(n) } : { x0: w / 2, dx: w }),
        ...(ny > 1 ? { y: c(ny) } : { y0: w / 2, dy: w }) };
}

// values (nx * ny, row-major y then x) as rows for a heatmap's z.
export function rows(values, nx, ny) {
    return Array.from({ length: ny }, (_, j) => values.slice(j * nx, (j + 1) * nx));
}

// [min, max] of the finite values of the arrays given.
export function jointRange(...arrays) {
    let lo = Infinity, hi = -Infinity;
    for (const a of arrays) {
        for (const v of a || []) {
            if (v === null || !Number.isFinite(v)) continue;
            lo = Math.min(lo, v);
            hi = Math.max(hi, v);
        }
    }
    return lo === Infinity ? [0, 1] : lo === hi ? [lo - 0.5, hi + 0.5] : [lo, hi];
}

// The values of an nx x ny map as a table in a <details> (for keyboards and screen readers).
export function valueTable(values, nx, ny) {
    const rows = [];
    for (let j = 0; j < ny; j++) {
        rows.push(h('tr', {}, h('th', { scope: 'row' }, j),
            Array.from({ length: nx }, (_, i) => h('td', {}, fmt(values[j * nx + i], 4)))));
    }
    return h('details', { class: 'values' }, h('summary', {}, 'Values'),
        h('table', { class: 'num' }, h('thead', {}, h('tr', {}, h('th', {}, 'row \\ col'),
            Array.from({ length: nx }, (_, i) => h('th', { scope: 'col' }, i)))),
        h('tbody', {}, rows)));
}
