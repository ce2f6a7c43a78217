// scan_overview.js: the Scan view's sub-frame overview: every pixel of the scan's sub_px x
// sub_px sub-frame with the map of its calibration from this scan, all on ONE colour scale
// (viridis, spanning every map shown), side by side at their places on the sensor (axes in µm
// from the POI's top-left corner, y downward, the pixel grid drawn); a pixel without a
// calibration from this scan is a grey placeholder. The maps come from the calibration search
// (GET /api/calibrations?sensor=&col_min=&col_max=&row_min=&row_max=, paged), keeping the
// calibrations whose scan_id is this scan: per pixel its current one, else the newest.
// A click on a pixel opens its Pixel view; the same links are listed for keyboards. Redrawn in
// place (the user's zoom kept) only when the calibrations shown change.
import { get } from './api.js';
import { fill, h } from './dom.js';
import { VIRIDIS, jointRange, pixelFrame, purgeIn, rows, showFigure, squareAxes }
    from './charts.js';

export const MAX_OVERVIEW_SUB_PX = 25; // 625 pixels: a larger sub-frame is not drawn (said so)
const PAGE = 1000; // the search's largest page (api/openapi.json)

// The calibrations from scan of its sub-frame's pixels: Map 'dcol,drow' -> Calibration.
export async function subframeCalibrations(scan) {
    const hs = Math.floor(scan.raster.sub_px / 2), c = scan.poi.col, r = scan.poi.row;
    const q = `sensor=${scan.sensor_id}&col_min=${c - hs}&col_max=${c + hs}&row_min=${r - hs}` +
        `&row_max=${r + hs}&limit=${PAGE}`;
    const out = new Map();
    for (let offset = 0; ; offset += PAGE) {
        const page = await get(`/api/calibrations?${q}&offset=${offset}`);
        for (const cal of page.items) { // newest first
            if (cal.scan_id !== scan.id) continue;
            const key = `${cal.pixel.col - c},${cal.pixel.row - r}`;
            const had = out.get(key);
            if (!had || (cal.current && !had.current)) out.set(key, cal);
        }
        if (page.items.length < PAGE || offset + PAGE >= (page.total ?? 0)) break;
    }
    return out;
}

// The overview of the sub-frame from cals (subframeCalibrations' answer): {spec} of its figure
// (charts.js showFigure) and {list} of links to the pixels (null for many).
export function overviewFigure(scan, pitch, cals) {
    const fr = pixelFrame(pitch), w = fr.w, m = scan.raster.sub_px, hs = Math.floor(m / 2);
    const maps = [...cals.values()].filter((c) => Array.isArray(c.S) && c.r > 0);
    const [cmin, cmax] = jointRange(...maps.map((c) => c.S));
    const data = [], shapes = [], missing = [];
    for (let drow = -hs; drow <= hs; drow++) {
        for (let dcol = -hs; dcol <= hs; dcol++) {
            const cal = cals.get(`${dcol},${drow}`);
            if (!cal || !Array.isArray(cal.S)) {
                missing.push([dcol, drow]);
                shapes.push({ type: 'rect', x0: dcol * w, x1: (dcol + 1) * w, y0: drow * w,
                    y1: (drow + 1) * w, fillcolor: '#d9dde4', line: { width: 0 },
                    layer: 'below' });
                continue;
            }
            // cells at the sub-pixel centres (i + 1/2) w / r of the pixel's place (x0 + k dx:
            // also right for r = 1, where an x array would leave Plotly to guess the width)
            const n = cal.r;
            data.push({ type: 'heatmap', name: `(${cal.pixel.col}, ${cal.pixel.row})`,
                x0: dcol * w + w / (2 * n), dx: w / n, y0: drow * w + w / (2 * n), dy: w / n,
                z: rows(cal.S, n, n), coloraxis: 'coloraxis',
                customdata: rows(cal.S.map(() => cal.id), n, n),
                meta: [cal.pixel.col, cal.pixel.row, cal.r],
                hovertemplate: `pixel (%{meta[0]}, %{meta[1]}), r = %{meta[2]}<br>` +
                    'S = %{z:.4g}<extra>calibration #%{customdata}</extra>' });
        }
    }
    for (let k = -hs; k <= hs + 1; k++) { // the pixel grid
        const line = { color: '#ffffff', width: 1.5 };
        shapes.push({ type: 'line', x0: k * w, x1: k * w, y0: -hs * w, y1: (hs + 1) * w, line });
        shapes.push({ type: 'line', y0: k * w, y1: k * w, x0: -hs * w, x1: (hs + 1) * w, line });
    }
    shapes.push({ type: 'rect', x0: 0, x1: w, y0: 0, y1: w, line: { color: '#e69f00', width: 3 },
        fillcolor: 'rgba(0,0,0,0)' });
    const range = [-hs * w, (hs + 1) * w];
    const spec = {
        title: `Sub-frame overview: ${maps.length} of ${m * m} pixels have a map from this ` +
            'scan, on one colour scale',
        testid: 'subframe-overview', height: 460, name: `subframe-${scan.id}`, data,
        layout: { ...squareAxes({ ...fr, xtitle: `x (${fr.unit}) from the POI's corner` }, '',
            [0, 1], range), shapes,
        coloraxis: { colorscale: VIRIDIS, cmin, cmax,
            colorbar: { title: { text: 'S (mean 1)' }, thickness: 14 } } },
        note: `Each square is one pixel of the sub-frame (the POI outlined in orange), its map ` +
            `S drawn inside it${missing.length ? `; grey: no calibration from this scan ` +
            `(${missing.length} pixels)` : ''}. Click a map to open its pixel.`,
        uirevision: `overview-${scan.id}`,
        dataset: { maps: String(maps.length), missing: String(missing.length) },
        onClick: (ev) => {
            const t = ev.points?.[0]?.data;
            if (t?.meta) {
                location.hash = `#/sensors/${scan.sensor_id}/pixels/${t.meta[0]}/${t.meta[1]}`;
            }
        },
    };
    const href = (c) => `#/sensors/${c.sensor_id}/pixels/${c.pixel.col}/${c.pixel.row}`;
    const list = maps.length <= 81 ? h('details', {}, h('summary', {}, 'The pixels\' maps'),
        h('ul', { class: 'plain' }, maps.map((c) => h('li', {}, h('a', { href: href(c) },
            `Pixel (${c.pixel.col}, ${c.pixel.row})`), `: calibration #${c.id}, r = ${c.r}` +
            (c.current ? ', current' : ', superseded'))))) : null;
    return { spec, list };
}

// The overview section's content for scan, drawn into slot: nothing for a sub-frame too large
// to draw, a note while no pixel has a map from the scan, else the figure, updated in place when
// already there and only when the calibrations shown (their ids and current flags) changed.
export async function drawOverview(slot, scan, pitch) {
    const note = (testid, text) => {
        purgeIn(slot);
        fill(slot, h('p', { class: 'muted', 'data-testid': testid }, text));
        delete slot.dataset.key;
    };
    if (scan.raster.sub_px > MAX_OVERVIEW_SUB_PX) {
        note('overview-large', `The ${scan.raster.sub_px}×${scan.raster.sub_px} sub-frame is ` +
            `too large for an overview (at most ${MAX_OVERVIEW_SUB_PX}×${MAX_OVERVIEW_SUB_PX}).`);
        return;
    }
    const cals = await subframeCalibrations(scan);
    if (!cals.size) {
        note('overview-empty', 'No pixel of the sub-frame has a calibration from this scan yet.');
        return;
    }
    const key = [...cals.values()].map((c) => `${c.id}${c.current ? 'c' : ''}`).sort().join(' ') +
        ` ${pitch}`;
    if (key === slot.dataset.key && slot.querySelector('.pgraph')) return;
    slot.dataset.key = key;
    const { spec, list } = overviewFigure(scan, pitch, cals);
    const fig = showFigure(slot, spec);
    while (fig.nextSibling) fig.nextSibling.remove(); // the list of the calibrations drawn before
    if (list) slot.append(list);
}
