// maps.js: the figures of one r x r IPS map, used by the Fit view and the Pixel view: the fitted
// S, the interpolated map (the paper's "interpolated IPS map", computed by the server: GET
// /api/fits/ID/interp or /api/calibrations/ID/interp, fit_interp_bicubic) and the uncertainties
// S_err, each a heatmap with its colour bar and the value under the pointer.
import { get } from './api.js';
import { failure, fill, fmt, h } from './dom.js';
import { heatmap } from './plots.js';

export const INTERP_N = 100; // points per axis of the interpolated map

// The sub-pixel readout of an r x r map over a pitch (um), or of unit coordinates when unknown.
function cellText(r, pitch, name, err) {
    return (i, j, v) => {
        const w = pitch ? pitch / r : 1 / r, u = pitch ? ' µm' : '';
        const e = err ? ` ± ${fmt(err[j * r + i], 2)}` : '';
        return `sub-pixel (${i}, ${j}), x ${fmt(i * w, 3)}–${fmt((i + 1) * w, 3)}${u}, ` +
            `y ${fmt(j * w, 3)}–${fmt((j + 1) * w, 3)}${u}: ${name} = ${fmt(v, 5)}${e}`;
    };
}

// The interpolated map from the server (interpPath: the route with its ?r= when any, without
// n), drawn into a figure that says "loading" until it arrives.
function interpFigure(interpPath, pitch) {
    const box = h('figure', { class: 'map', dataset: { testid: 'map-interp', state: 'loading' } },
        h('figcaption', {}, 'Interpolated'), h('p', { class: 'muted' }, 'Loading…'));
    const sep = interpPath.includes('?') ? '&' : '?';
    get(`${interpPath}${sep}n=${INTERP_N}`).then((m) => {
        const w = pitch || 1, u = pitch ? ' µm' : '';
        // output point k of n sits at (k + 1/2) / n of the pitch (docs/api.md)
        const fig = heatmap({ values: m.S, nx: m.n, ny: m.n, title: `Interpolated (${m.method})`,
            testid: 'map-interp', describe: (i, j, v) =>
                `x = ${fmt((i + 0.5) / m.n * w, 3)}${u}, y = ${fmt((j + 0.5) / m.n * w, 3)}${u}: ` +
                `S ≈ ${fmt(v, 5)}` });
        fig.dataset.state = 'ready';
        box.replaceWith(fig);
    }).catch((err) => {
        box.dataset.state = 'failed';
        fill(box, h('figcaption', {}, 'Interpolated'), failure(err));
    });
    return box;
}

// The figures of an r x r map: S, its interpolated map (from interpPath), S_err.
export function mapFigures(S, S_err, r, pitch, interpPath, label = 'S') {
    const figs = [
        heatmap({ values: S, nx: r, ny: r, title: `Fitted sensitivity ${label} (${r}×${r})`,
            testid: 'map-S', describe: cellText(r, pitch, 'S', S_err), table: true }),
        interpFigure(interpPath, pitch),
    ];
    if (S_err) {
        figs.push(heatmap({ values: S_err, nx: r, ny: r, title: 'Uncertainty S_err (1σ)',
            cmap: 'magma', testid: 'map-Serr', describe: cellText(r, pitch, 'S_err'),
            table: true }));
    }
    return figs;
}
