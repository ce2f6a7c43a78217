// plots.js: the scan page's hand-drawn heatmaps of rasters on <canvas> with a colour bar, the
// value under the pointer (or the keyboard cursor) and a table of the values (charts.js). The
// maps, the model selection and the calibrations are Plotly figures now (charts.js).
import { valueTable } from './charts.js';
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
