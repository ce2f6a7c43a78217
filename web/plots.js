// plots.js: the pictures of the dashboard: heatmaps of maps and rasters on <canvas> with a colour
// bar, the value under the pointer (or the keyboard cursor) and a table of the values; and line
// plots as inline SVG (the model-selection plot: chi2, AIC and BIC against r, best r marked).
import { fmt, h } from './dom.js';

// Perceptually uniform colour maps (matplotlib's viridis and magma), 9 stops each.
const MAPS = {
    viridis: ['#440154', '#472d7b', '#3b528b', '#2c728e', '#21918c', '#28ae80', '#5ec962',
        '#addc30', '#fde725'],
    magma: ['#000004', '#1c1044', '#4f127b', '#812581', '#b5367a', '#e55964', '#fb8761',
        '#fec287', '#fcfdbf'],
};
const NAN_RGB = [160, 160, 160];
const stopCache = {};

function stops(name) {
    return stopCache[name] ??= MAPS[name].map((s) => [1, 3, 5].map((k) =>
        parseInt(s.slice(k, k + 2), 16)));
}

// [r, g, b] of t in [0, 1] on colour map name.
export function colour(name, t) {
    if (!Number.isFinite(t)) return NAN_RGB;
    const s = stops(name), x = Math.min(Math.max(t, 0), 1) * (s.length - 1);
    const k = Math.min(Math.floor(x), s.length - 2), f = x - k;
    return [0, 1, 2].map((c) => Math.round(s[k][c] + f * (s[k + 1][c] - s[k][c])));
}

export function finiteRange(values) {
    let lo = Infinity, hi = -Infinity;
    for (const v of values) {
        if (v === null || !Number.isFinite(v)) continue;
        if (v < lo) lo = v;
        if (v > hi) hi = v;
    }
    if (lo === Infinity) return [0, 1];
    if (lo === hi) return [lo - 0.5, hi + 0.5];
    return [lo, hi];
}

// Draws values (nx * ny, row-major y then x, row 0 at the top) into canvas, cells as blocks.
function paint(canvas, values, nx, ny, cmap, range, cssSize) {
    const dpr = window.devicePixelRatio || 1;
    canvas.width = Math.round(cssSize.w * dpr);
    canvas.height = Math.round(cssSize.h * dpr);
    canvas.style.width = `${cssSize.w}px`;
    canvas.style.height = `${cssSize.h}px`;
    const small = document.createElement('canvas');
    small.width = nx;
    small.height = ny;
    const sctx = small.getContext('2d');
    const img = sctx.createImageData(nx, ny);
    const [lo, hi] = range;
    for (let k = 0; k < nx * ny; k++) {
        const v = values[k];
        const rgb = v === null || !Number.isFinite(v) ? NAN_RGB
            : colour(cmap, (v - lo) / (hi - lo));
        img.data.set([rgb[0], rgb[1], rgb[2], 255], 4 * k);
    }
    sctx.putImageData(img, 0, 0);
    const ctx = canvas.getContext('2d');
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(small, 0, 0, canvas.width, canvas.height);
    return ctx;
}

function colourBar(cmap, range, height, unit) {
    const bar = h('canvas', { class: 'cbar', width: 1, height: 128, 'aria-hidden': 'true' });
    bar.style.height = `${height}px`;
    const ctx = bar.getContext('2d');
    for (let y = 0; y < 128; y++) {
        const [r, g, b] = colour(cmap, 1 - y / 127);
        ctx.fillStyle = `rgb(${r},${g},${b})`;
        ctx.fillRect(0, y, 1, 1);
    }
    const [lo, hi] = range;
    const ticks = h('div', { class: 'cbar-ticks' },
        [hi, (lo + hi) / 2, lo].map((v) => h('span', {}, fmt(v, 3))));
    ticks.style.height = `${height}px`;
    return h('div', { class: 'cbar-wrap', title: unit ? `colour scale (${unit})` : 'colour scale' },
        bar, ticks);
}

// A heatmap figure. opts: values, nx, ny, title, cmap ('viridis'), range ([lo, hi], default the
// data's), size (CSS px of the longer side), aspect (height / width, default ny / nx),
// describe(i, j, v) -> hover text, outline(ctx, w, h) -> extra drawing, table (bool: add a
// table of the values), testid, unit, thumb (bool: the bare canvas, no caption or readout).
export function heatmap(opts) {
    const { values, nx, ny, title, cmap = 'viridis', size = 220, describe, testid } = opts;
    const range = opts.range || finiteRange(values);
    const aspect = opts.aspect ?? ny / nx;
    const css = aspect <= 1 ? { w: size, h: Math.round(size * aspect) }
        : { w: Math.round(size / aspect), h: size };
    const label = `${title}: ${nx} by ${ny} map, values ${fmt(range[0], 3)} to ${fmt(range[1], 3)}`;
    const canvas = h('canvas', { class: 'heat', tabindex: '0', role: 'img', 'aria-label': label,
        dataset: { nx, ny, min: range[0], max: range[1] } });
    const ctx = paint(canvas, values, nx, ny, opts.cmap || cmap, range, css);
    if (opts.outline) opts.outline(ctx, canvas.width, canvas.height);
    if (opts.thumb) {
        canvas.removeAttribute('tabindex');
        return canvas;
    }
    const readout = h('output', { class: 'readout', 'aria-live': 'polite' },
        'Point at a cell for its value');
    const say = (i, j) => {
        const v = values[j * nx + i];
        readout.textContent = describe ? describe(i, j, v) : `(${i}, ${j}): ${fmt(v, 5)}`;
    };
    const cursor = { i: 0, j: 0 };
    canvas.addEventListener('mousemove', (e) => {
        const b = canvas.getBoundingClientRect();
        cursor.i = Math.min(nx - 1, Math.max(0, Math.floor((e.clientX - b.left) / b.width * nx)));
        cursor.j = Math.min(ny - 1, Math.max(0, Math.floor((e.clientY - b.top) / b.height * ny)));
        say(cursor.i, cursor.j);
    });
    canvas.addEventListener('keydown', (e) => {
        const moves = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1],
            ArrowDown: [0, 1] };
        const m = moves[e.key];
        if (!m) return;
        e.preventDefault();
        cursor.i = Math.min(nx - 1, Math.max(0, cursor.i + m[0]));
        cursor.j = Math.min(ny - 1, Math.max(0, cursor.j + m[1]));
        say(cursor.i, cursor.j);
    });
    canvas.addEventListener('focus', () => say(cursor.i, cursor.j));
    const fig = h('figure', { class: 'map', dataset: { testid: testid || '' } },
        h('figcaption', {}, title),
        h('div', { class: 'map-row' }, canvas, colourBar(cmap, range, css.h, opts.unit)),
        readout);
    if (opts.table && nx * ny <= 400) fig.append(valueTable(values, nx, ny));
    return fig;
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

// "Nice" tick values between lo and hi (about n of them).
function ticks(lo, hi, n = 5) {
    const span = hi - lo || Math.abs(hi) || 1;
    const step0 = span / n, mag = 10 ** Math.floor(Math.log10(step0));
    const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => span / s <= n) || 10 * mag;
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) {
        out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
    }
    return out;
}

// 10^k written with superscript digits.
function power10(k) {
    const sup = { '-': '⁻', 0: '⁰', 1: '¹', 2: '²', 3: '³', 4: '⁴', 5: '⁵', 6: '⁶', 7: '⁷',
        8: '⁸', 9: '⁹' };
    return `10${[...String(k)].map((c) => sup[c]).join('')}`;
}

// A line plot as SVG. opts: title, xlabel, ylabel, log (y axis), series [{name, cls, points:
// [[x, y]]}], marks [{x, label, cls}] (vertical markers), xticks (values), width, height.
export function linePlot(opts) {
    const W = opts.width || 420, H = opts.height || 230;
    const m = { l: 62, r: 12, t: 24, b: 40 };
    const pts = opts.series.flatMap((s) => s.points).filter(([, y]) => Number.isFinite(y) &&
        (!opts.log || y > 0));
    const xs = pts.map(([x]) => x), ys = pts.map(([, y]) => (opts.log ? Math.log10(y) : y));
    let [x0, x1] = [Math.min(...xs), Math.max(...xs)];
    let [y0, y1] = [Math.min(...ys), Math.max(...ys)];
    if (x0 === x1) [x0, x1] = [x0 - 1, x1 + 1];
    if (y0 === y1) [y0, y1] = [y0 - 1, y1 + 1];
    const pad = (y1 - y0) * 0.06;
    y0 -= pad;
    y1 += pad;
    const X = (x) => m.l + (x - x0) / (x1 - x0) * (W - m.l - m.r);
    const Y = (y) => H - m.b - ((opts.log ? Math.log10(y) : y) - y0) / (y1 - y0) *
        (H - m.t - m.b);
    const svg = h('svg:svg', { viewBox: `0 0 ${W} ${H}`, width: W, height: H, role: 'img',
        'aria-label': opts.title, class: 'plot' });
    svg.append(h('svg:text', { x: m.l, y: 15, class: 'ptitle' }, opts.title));
    const yt = opts.log ? ticks(y0, y1, 4).filter((v) => Number.isInteger(v)).map((v) => 10 ** v)
        : ticks(y0, y1, 5);
    for (const v of yt) {
        const y = Y(v);
        if (y < m.t - 1 || y > H - m.b + 1) continue;
        svg.append(h('svg:line', { x1: m.l, x2: W - m.r, y1: y, y2: y, class: 'grid' }),
            h('svg:text', { x: m.l - 6, y: y + 4, class: 'tick', 'text-anchor': 'end' },
                opts.log ? power10(Math.round(Math.log10(v))) : fmt(v, 3)));
    }
    for (const v of opts.xticks || ticks(x0, x1, 8)) {
        svg.append(h('svg:text', { x: X(v), y: H - m.b + 16, class: 'tick',
            'text-anchor': 'middle' }, v));
    }
    svg.append(h('svg:line', { x1: m.l, x2: W - m.r, y1: H - m.b, y2: H - m.b, class: 'axis' }),
        h('svg:line', { x1: m.l, x2: m.l, y1: m.t, y2: H - m.b, class: 'axis' }),
        h('svg:text', { x: (m.l + W - m.r) / 2, y: H - 6, class: 'alabel',
            'text-anchor': 'middle' }, opts.xlabel),
        h('svg:text', { x: 12, y: (m.t + H - m.b) / 2, class: 'alabel', 'text-anchor': 'middle',
            transform: `rotate(-90 12 ${(m.t + H - m.b) / 2})` }, opts.ylabel));
    for (const mk of opts.marks || []) {
        const left = X(mk.x) > W - m.r - 100; // near the right edge: label on the left
        svg.append(h('svg:line', { x1: X(mk.x), x2: X(mk.x), y1: m.t, y2: H - m.b,
            class: `mark ${mk.cls || ''}` }),
        h('svg:text', { x: X(mk.x) + (left ? -3 : 3), y: m.t + 10 + (mk.row || 0) * 12,
            'text-anchor': left ? 'end' : 'start', class: `mark-label ${mk.cls || ''}` },
        mk.label));
    }
    for (const s of opts.series) {
        const p = s.points.filter(([, y]) => Number.isFinite(y) && (!opts.log || y > 0));
        svg.append(h('svg:polyline', { class: `line ${s.cls}`,
            points: p.map(([x, y]) => `${X(x).toFixed(1)},${Y(y).toFixed(1)}`).join(' ') }));
        for (const [x, y] of p) {
            svg.append(h('svg:circle', { cx: X(x), cy: Y(y), r: s.best?.includes(x) ? 6 : 3,
                class: `dot ${s.cls}${s.best?.includes(x) ? ' best' : ''}` },
            h('svg:title', {}, `${s.name} at r = ${x}: ${fmt(y, 6)}`)));
        }
    }
    const legend = h('div', { class: 'legend' }, opts.series.map((s) =>
        h('span', { class: `key ${s.cls}` }, s.name)));
    return h('figure', { class: 'plot-fig' }, svg, legend);
}
