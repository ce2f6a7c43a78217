// scan_frames.js: the Scan view's panel of one raster point's frames (GET
// /api/scans/ID/points/INDEX: the mean sub-frame and every raw frame, sub_px x sub_px, row-major):
// the mean beside one raw frame (chosen by number) on one colour scale, on axes of pixel offsets
// from the pixel of interest (y downward), the POI outlined. Opened by a click on a spot of the
// raster or the geometry figure, or from the keyboard (the point's number, previous / next).
import { get } from './api.js';
import { failure, field, fill, fmt, fmtTime, h } from './dom.js';
import { VIRIDIS, jointRange, plotFigure, purgeIn, rows } from './charts.js';

// The panel; its show(index) opens a point, setTotal(n) sets the scan's points_total.
// done(): points stored so far.
export function framesPanel(scanId, done) {
    const body = h('div', { 'data-testid': 'point-frames' },
        h('p', { class: 'muted' }, 'Click a spot of the raster or of the geometry figure, or ' +
            'give its number here, to see the frames the camera took there.'));
    const input = field('Point (raster order)', { type: 'number', min: 0, step: 1,
        'data-testid': 'point-index' });
    const box = h('form', { class: 'scan-tools', 'aria-label': 'Show a point\'s frames',
        onsubmit: (e) => {
            e.preventDefault();
            const k = Number(input.querySelector('input').value);
            if (Number.isInteger(k)) show(k);
        } }, input, h('button', { type: 'submit', class: 'small' }, 'Show frames'),
    h('button', { type: 'button', class: 'small', onclick: () => step(-1) }, '← Previous'),
    h('button', { type: 'button', class: 'small', onclick: () => step(1) }, 'Next →'));
    const panel = h('section', { class: 'panel', 'aria-labelledby': 'frames-h' },
        h('h3', { id: 'frames-h' }, 'Raw frames of a point'), box, body);
    let current = null, seq = 0;

    function step(d) {
        const k = (current ?? -d) + d;
        if (k >= 0 && k < Math.max(done(), 1)) show(k);
    }

    async function show(index) {
        current = index;
        input.querySelector('input').value = String(index);
        const mine = ++seq;
        body.dataset.state = 'loading';
        let p;
        try {
            p = await get(`/api/scans/${scanId}/points/${index}`);
        } catch (err) {
            if (mine !== seq) return;
            purgeIn(body);
            fill(body, failure(err));
            body.dataset.state = 'failed';
            return;
        }
        if (mine !== seq) return;
        purgeIn(body);
        fill(body, pointView(p));
        body.dataset.state = 'ready';
        body.dataset.point = String(index);
    }

    const setTotal = (n) => input.querySelector('input').setAttribute('max', String(n - 1));
    return { el: panel, show, setTotal };
}

// The mean sub-frame beside raw frame k (1-based chooser) on one colour scale.
function pointView(p) {
    const m = p.sub_px, hs = Math.floor(m / 2);
    const offs = Array.from({ length: m }, (_, k) => k - hs);
    const [cmin, cmax] = jointRange(p.mean, ...p.raw);
    const chooser = field(`Raw frame (1..${p.frames})`, { type: 'number', min: 1, max: p.frames,
        step: 1, value: 1, 'data-testid': 'frame-number' });
    const slot = h('div', {});
    const heat = (z, name, ax) => ({ type: 'heatmap', x: offs, y: offs, z: rows(z, m, m), name,
        coloraxis: 'coloraxis', xaxis: `x${ax}`, yaxis: `y${ax}`,
        hovertemplate: `pixel (%{x}, %{y}) from the POI<br>%{z:.6g} DN<extra>${name}</extra>` });
    const axes = (k, domain) => ({
        [`xaxis${k}`]: { title: { text: 'column offset (pixels)' }, domain, dtick: 1,
            zeroline: false, anchor: `y${k}`, constrain: 'domain' },
        [`yaxis${k}`]: { title: { text: k ? '' : 'row offset (pixels), downward' },
            autorange: 'reversed', dtick: 1, zeroline: false, scaleanchor: `x${k}`,
            anchor: `x${k}`, constrain: 'domain' },
    });
    const poi = (k) => ({ type: 'rect', xref: `x${k}`, yref: `y${k}`, x0: -0.5, x1: 0.5,
        y0: -0.5, y1: 0.5, line: { color: '#ffffff', width: 2, dash: 'dash' } });
    const draw = (k) => {
        purgeIn(slot);
        fill(slot, plotFigure({ title: `Mean of ${p.frames} frames beside raw frame ${k}`,
            testid: 'frames-plot', height: 340, name: `point-${p.point_index}-frame-${k}`,
            data: [heat(p.mean, 'mean', ''), heat(p.raw[k - 1], `frame ${k}`, 2)],
            layout: { ...axes('', [0, 0.42]), ...axes(2, [0.55, 0.97]),
                coloraxis: { colorscale: VIRIDIS, cmin, cmax,
                    colorbar: { title: { text: 'DN' }, thickness: 12 } },
                shapes: [poi(''), poi(2)] },
            // on a phone: the mean above the frame
            stacked: { height: 600, layout: { ...axes('', [0, 1]), ...axes(2, [0, 1]),
                yaxis: { ...axes('', [0, 1]).yaxis, domain: [0.56, 0.96] },
                yaxis2: { ...axes(2, [0, 1]).yaxis2, domain: [0, 0.4] } } },
            note: 'One colour scale for both. The dashed square is the pixel of interest.' }));
    };
    const inp = chooser.querySelector('input');
    inp.addEventListener('input', () => {
        const k = Math.round(Number(inp.value));
        if (k >= 1 && k <= p.frames) draw(k);
    });
    draw(1);
    const [x, y, z] = p.stage_um;
    return [h('p', { 'data-testid': 'point-facts' }, `Point ${p.point_index}: stage at x = ` +
        `${fmt(x, 6)} µm, y = ${fmt(y, 6)} µm, z = ${fmt(z, 6)} µm; exposure ` +
        `${fmt(p.exposure_us)} µs; ${p.frames} frames of ${m}×${m} pixels, taken ` +
        `${fmtTime(p.captured_ms)}.`), h('div', { class: 'scan-tools' }, chooser), slot];
}
