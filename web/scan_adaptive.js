// scan_adaptive.js: the Scan view's geometry figure of an adaptive scan (docs/api.md, "strategy"):
// the positions the planner chose over the pixel of interest, in the order taken (the point
// index), from the POI's response at every stored point (GET /api/scans/ID/pixels/0/0?all=1:
// positions from the POI's top-left corner, y downward). The starting raster is drawn grey, the
// batches coloured by their order, joined by the stage's path; the title says the strategy and,
// once the scan stopped, why (setup.adaptive). A spec for charts.js showFigure.
import { VIRIDIS, outline, pixelFrame, squareAxes } from './charts.js';

const START = '#8a93a6', PATH = 'rgba(0, 114, 178, 0.35)';

// The figure of scan (its strategy and setup) from data (the POI's scan file); onPoint(index)
// on a click on a position.
export function adaptiveSpec(scan, data, onPoint) {
    const st = scan.strategy, fr = pixelFrame(data.pitch_um), w = fr.w;
    const n = data.x_um.length, n0 = Math.min(n, st.start_grid * st.start_grid);
    const scale = fr.um ? 1 : 1 / data.pitch_um;
    const xs = data.x_um.map((v) => v * scale), ys = data.y_um.map((v) => v * scale);
    const idx = xs.map((_, k) => k);
    const hover = `point %{customdata}<br>x %{x:.3f}${fr.u}, y %{y:.3f}${fr.u}`;
    const data2 = [
        { type: 'scatter', mode: 'lines', name: 'stage path', x: xs, y: ys, hoverinfo: 'skip',
            line: { color: PATH, width: 1 } },
        { type: 'scatter', mode: 'markers', name: `starting ${st.start_grid}×${st.start_grid}`,
            x: xs.slice(0, n0), y: ys.slice(0, n0), customdata: idx.slice(0, n0),
            marker: { color: START, size: 7, symbol: 'square' },
            hovertemplate: `${hover}<extra>start</extra>` },
    ];
    if (n > n0) {
        data2.push({ type: 'scatter', mode: 'markers', name: 'planned batches',
            x: xs.slice(n0), y: ys.slice(n0), customdata: idx.slice(n0),
            marker: { color: idx.slice(n0), colorscale: VIRIDIS, cmin: n0,
                cmax: Math.max(n, n0 + 1), size: 7,
                colorbar: { title: { text: 'order taken' }, thickness: 12 } },
            hovertemplate: `${hover}<extra>batch</extra>` });
    }
    const m = w * 0.04, range = [-m, w + m];
    const layout = { ...squareAxes({ ...fr, xtitle: `x (${fr.unit}) from the POI's corner` },
        '', [0, 1], range), shapes: [outline(fr)], showlegend: true,
    legend: { orientation: 'h', x: 0, y: -0.18, yanchor: 'top' },
    margin: { l: 60, r: 20, t: 20, b: 90 } };
    const end = scan.setup?.adaptive;
    const why = end ? `stopped (${end.stop}) at ${end.points} points, expected error ` +
        `${end.expected_err.toPrecision(3)}` : `${n} of at most ${st.max_points} points so far`;
    return { title: `Adaptive scan: ${why}`, testid: 'scan-geometry', data: data2, layout,
        height: 440, name: `adaptive-${scan.id}`, uirevision: `adaptive-${scan.id}`,
        dataset: { points: String(n), done: String(n), strategy: 'adaptive' },
        onClick: onPoint ? (ev) => {
            const p = ev.points?.[0];
            if (p && Number.isInteger(p.customdata)) onPoint(p.customdata);
        } : null,
        note: `The pixel of interest (${scan.poi.col}, ${scan.poi.row}), outlined: the starting ` +
            `raster of cell centres (grey), then batches of ${st.batch} where the kriged map ` +
            `was least sure (target ${st.target_err}), in the order taken along the stage's ` +
            'path. Click a position for its raw frames.' };
}
