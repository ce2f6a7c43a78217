// scan_detail.js: the Scan view (#/scans/ID): the scan's state and setup, the scan geometry
// (spot positions over the sub-frame; an adaptive scan's chosen positions: scan_adaptive.js),
// the response raster of any pixel of the sub-frame (filling in while the scan runs; linear or
// log colour, the whole raster or the pixel, CSV and JSON download), a point's raw frames
// (scan_frames.js), the sub-frame overview of the pixels' maps from this scan
// (scan_overview.js), the fit jobs of the scan with their results, and the form to fit another
// pixel (fit_form.js). Plotly figures: scan_plots.js. Live from /api/events, and re-read every
// few seconds while the scan or a fit is active.
import { ApiError, get, post } from './api.js';
import { errorBox, failure, fill, fmt, fmtTime, h, showError, stateBadge } from './dom.js';
import { buildFitForm } from './fit_form.js';
import { requestRules } from './rules.js';
import { purgeIn, showFigure } from './charts.js';
import { framesPanel } from './scan_frames.js';
import { drawOverview } from './scan_overview.js';
import { adaptiveSpec } from './scan_adaptive.js';
import { downloadButton, geometrySpec, rasterCsv, rasterSpec } from './scan_plots.js';
import { ACTIVE, POLL_MS, progressCell, sensorName, setProgress } from './scan_state.js';

export function renderScan(root, id, ctx) {
    let scan = null, sensor = null, closed = false, fitsTimer = null, rasterAt = 0;
    let rasterData = null, rasterSeq = 0, geoKey = '', rasterKey = '';
    const sel = { dcol: 0, drow: 0, colourMode: 'linear', zoom: 'all' }; // what the raster shows
    const head = h('h2', {}, `Scan #${id}`);
    const summary = h('section', { class: 'panel', 'aria-label': 'Scan summary' });
    const geometry = h('section', { class: 'panel', 'aria-labelledby': 'geometry-h' },
        h('h3', { id: 'geometry-h' }, 'Scan geometry'));
    const geoSlot = h('div', {});
    geometry.append(geoSlot);
    const rasterTools = h('div', { class: 'scan-tools' });
    const rasterSlot = h('div', {}, h('p', { class: 'muted' }, 'Loading…'));
    const raster = h('section', { class: 'panel', 'aria-labelledby': 'raster-h' },
        h('h3', { id: 'raster-h' }, 'Response raster of a pixel'), rasterTools, rasterSlot);
    const frames = framesPanel(id, () => scan?.points_done ?? 0);
    const overviewSlot = h('div', {}, h('p', { class: 'muted' }, 'When the scan is done: the ' +
        'maps of the sub-frame\'s pixels fitted from it, on one colour scale.'));
    const overview = h('section', { class: 'panel', 'aria-labelledby': 'overview-h' },
        h('h3', { id: 'overview-h' }, 'Sub-frame overview'), overviewSlot);
    const fitTable = h('div', {}), fitFormBox = h('div', {});
    const fits = h('section', { class: 'panel', 'aria-labelledby': 'fits-h' },
        h('h3', { id: 'fits-h' }, 'Fits of this scan'), fitTable, fitFormBox);
    const headMsg = errorBox();
    fill(root, h('p', { class: 'crumbs' }, h('a', { href: '#/scans' }, '← Scans')),
        h('div', { class: 'title-row' }, head), h('div', {}, headMsg),
        h('div', { class: 'two-col even' }, summary, geometry),
        h('div', { class: 'two-col even' }, raster, frames.el), overview, fits);

    async function loadScan() {
        const first = !scan;
        scan = await get(`/api/scans/${id}`);
        sensor ??= await get(`/api/sensors/${scan.sensor_id}`).catch(() => null);
        drawHead();
        drawSummary(sensor);
        if (first) {
            buildRasterTools();
            frames.setTotal(scan.raster.points_total);
        }
        drawGeometry();
    }

    const pitch = () => sensor?.pitch_um ?? rasterData?.pitch_um;

    // The geometry figure, redrawn (in place, the user's zoom kept) when the pixel shown or the
    // points stored change.
    // An adaptive scan's positions are the planner's, read from the POI's stored points.
    function drawGeometry() {
        const key = `${scan?.points_done} ${sel.dcol} ${sel.drow} ${pitch()} ${scan?.state}`;
        if (!scan || !pitch() || key === geoKey) return;
        geoKey = key;
        if (scan.strategy?.kind === 'adaptive') {
            if (!scan.setup) return; // nothing measured yet
            get(`/api/scans/${id}/pixels/0/0?all=1`).then((d) => {
                if (!closed && key === geoKey) {
                    showFigure(geoSlot, adaptiveSpec(scan, d, (k) => frames.show(k)));
                }
            }).catch((e) => {
                if (!closed) {
                    purgeIn(geoSlot);
                    fill(geoSlot, failure(e));
                }
            });
            return;
        }
        showFigure(geoSlot, geometrySpec(scan, pitch(), { ...sel }, (k) => frames.show(k)));
    }

    // The raster's controls: the pixel (offsets from the POI), the colour scale, the zoom and
    // the downloads; built once.
    function buildRasterTools() {
        const hs = Math.floor(scan.raster.sub_px / 2);
        const offsets = Array.from({ length: 2 * hs + 1 }, (_, k) => k - hs);
        const pick = (label, key) => h('label', { class: 'fld' }, h('span', { class: 'lbl' },
            label), h('select', { 'data-testid': `raster-${key}`, onchange: (e) => {
            sel[key] = Number(e.target.value);
            loadRaster();
            drawGeometry();
        } }, offsets.map((o) => h('option', { value: o, selected: o === 0 }, String(o)))));
        const radios = (name, legend, opts, key) => h('fieldset', { class: 'radios-box' },
            h('legend', {}, legend), opts.map(([v, text]) => h('label', { class: 'inline' },
                h('input', { type: 'radio', name: `${name}-${id}`, value: v,
                    'data-testid': `${name}-${v}`, checked: sel[key] === v,
                    onchange: () => {
                        sel[key] = v;
                        drawRaster();
                    } }), text)));
        const base = () => `scan${id}-pixel${sel.dcol}_${sel.drow}-raster`;
        fill(rasterTools,
            pick('Column offset (dcol)', 'dcol'), pick('Row offset (drow)', 'drow'),
            radios('colour', 'Colour', [['linear', 'linear'], ['log', 'log']], 'colourMode'),
            radios('zoom', 'Show', [['all', 'whole raster'], ['pixel', 'the pixel']], 'zoom'),
            h('div', { class: 'downloads' },
                downloadButton('Download CSV', () => `${base()}.csv`, 'text/csv',
                    () => (rasterData ? rasterCsv(rasterData) : null), 'raster-csv'),
                downloadButton('Download JSON', () => `${base()}.json`, 'application/json',
                    () => (rasterData ? JSON.stringify(rasterData) : null),
                    'raster-json')));
    }

    function drawHead() {
        if (head.dataset.state === scan.state) return; // keep the button under the pointer
        head.dataset.state = scan.state;
        const btn = ACTIVE.has(scan.state) ? h('button', { type: 'button', class: 'small',
            onclick: async () => {
                try {
                    await post(`/api/scans/${id}/cancel`);
                    await loadScan();
                } catch (err) {
                    showError(headMsg.parentElement, err);
                }
            } }, 'Cancel scan') : null;
        fill(head, `Scan #${id} `, stateBadge(scan.state), btn ? ' ' : null, btn);
    }

    // An adaptive scan's strategy and, once it stopped, why (docs/api.md "strategy").
    function adaptiveRow(s) {
        const st = s.strategy, r = s.raster, end = s.setup?.adaptive;
        return ['Adaptive', `${st.start_grid}×${st.start_grid} start, then batches of ` +
            `${st.batch} until the expected error is ${fmt(st.target_err)} or ` +
            `${st.max_points} points` + (end ? `: stopped (${end.stop}) at ${end.points} ` +
            `points, expected error ${fmt(end.expected_err)}` : '') + `; ${r.frames} frames ` +
            `each, ${r.sub_px}×${r.sub_px} sub-frame`];
    }

    function drawSummary(sensor) {
        const s = scan, o = s.optics, r = s.raster;
        const rows = [
            ['Sensor', sensor ? `${sensorName(sensor)} (${sensor.n_cols}×${sensor.n_rows}, ` +
                `${fmt(sensor.pitch_um)} µm pitch)` : `#${s.sensor_id}`],
            ['Pixel of interest', `(${s.poi.col}, ${s.poi.row})`],
            ['Optics', `λ = ${fmt(o.wavelength_nm)} nm, NA = ${fmt(o.na)}, spot radius ` +
                `R = ${fmt(o.spot_radius_um)} µm`],
            s.strategy?.kind === 'adaptive' ? adaptiveRow(s)
                : ['Raster', `${r.area_px}×${r.area_px} pixels in ${fmt(r.step_um)} µm steps: ` +
                `${r.points_per_axis}×${r.points_per_axis} = ${r.points_total} points, ` +
                `${r.frames} frames each, ${r.sub_px}×${r.sub_px} sub-frame`],
            ['Exposure', `${fmt(s.exposure_us)} µs requested` +
                (s.setup?.exposure_us ? `, ${fmt(s.setup.exposure_us)} µs set` : '')],
            ['Created', fmtTime(s.created_ms)], ['Started', fmtTime(s.started_ms)],
            ['Finished', fmtTime(s.finished_ms)],
        ];
        if (s.error) rows.push(['Error', s.error]);
        const prog = h('div', { class: 'progress-line' }, progressCell(s));
        fill(summary, h('h3', {}, 'State'), prog,
            h('dl', { class: 'facts' }, rows.map(([k, v]) => [h('dt', {}, k), h('dd', {}, v)])),
            s.setup ? h('details', {}, h('summary', {}, 'Bench setup (centring, focus)'),
                h('pre', { class: 'json' }, JSON.stringify(s.setup, null, 2))) : null);
    }

    // The raster of the chosen pixel (every point), then its figure; while the scan runs
    // (fresh false) not re-read when it has every point stored so far; not asked for before a
    // point is stored (the API answers 409 before the scan's setup).
    async function loadRaster(fresh = true) {
        if (scan && !(scan.points_done > 0)) {
            rasterData = null;
            rasterKey = '';
            purgeIn(rasterSlot);
            fill(rasterSlot, h('p', { class: 'muted' }, 'No points stored yet.'));
            return;
        }
        const have = rasterData && rasterData.dcol === sel.dcol && rasterData.drow === sel.drow;
        if (!fresh && have && rasterData.x_um.length === scan?.points_done) return;
        rasterAt = Date.now();
        const mine = ++rasterSeq, path = `/api/scans/${id}/pixels/${sel.dcol}/${sel.drow}?all=1`;
        let data;
        try {
            data = await get(path);
        } catch (err) {
            if (mine !== rasterSeq) return;
            purgeIn(rasterSlot);
            fill(rasterSlot, failure(err));
            return;
        }
        if (mine !== rasterSeq) return;
        rasterData = data;
        drawRaster();
        drawGeometry();
    }

    // The raster's figure, redrawn only when what it shows changed (a cheap key: the pixel, the
    // points stored, the colour and the zoom), in place (Plotly.react): the user's zoom and pan
    // survive the refreshes of a running scan.
    function drawRaster() {
        if (!rasterData) return;
        const d = rasterData, key = `${d.dcol} ${d.drow} ${d.x_um.length} ${sel.colourMode} ` +
            `${sel.zoom}`;
        if (key === rasterKey && rasterSlot.querySelector('.pgraph')) return;
        rasterKey = key;
        const spec = rasterSpec(d, scan, { ...sel, log: sel.colourMode === 'log',
            onPoint: (k) => frames.show(k) });
        if (spec) {
            showFigure(rasterSlot, spec);
        } else {
            purgeIn(rasterSlot);
            fill(rasterSlot, h('p', { class: 'muted' }, 'No points stored yet.'));
        }
    }

    async function loadOverview() {
        if (!scan || scan.state !== 'done' || !pitch()) return;
        await drawOverview(overviewSlot, scan, pitch()).catch((err) => {
            purgeIn(overviewSlot);
            fill(overviewSlot, failure(err));
            delete overviewSlot.dataset.key;
        });
    }

    async function loadFits() {
        const [jobs, list] = await Promise.all([get(`/api/jobs?scan=${id}&kind=fit&limit=100`),
            get(`/api/scans/${id}/fits?limit=100`)]);
        const byFit = new Map(list.items.map((f) => [f.id, f]));
        const rows = jobs.items.map((j) => {
            const f = j.fit_id ? byFit.get(j.fit_id) : null;
            const px = j.params || {};
            return h('tr', { dataset: { jobId: j.id, state: j.state } },
                h('td', {}, `#${j.id}`), h('td', {}, px.pixels === 'all' ? 'every covered pixel'
                    : `(${px.dcol ?? 0}, ${px.drow ?? 0})`),
                h('td', {}, stateBadge(j.state), px.pixels === 'all'
                    ? h('div', { class: 'muted', 'data-testid': 'pixels-done' },
                        `${j.points_done ?? 0} pixels stored (${Math.round(100 * (j.progress ?? 0))} %)`)
                    : null, j.error ? h('div', { class: 'err' }, j.error) : null),
                h('td', {}, f ? h('a', { href: `#/fits/${f.id}`, 'data-testid': 'fit-link' },
                    `Fit #${f.id}`) : '–'),
                h('td', { class: 'num' }, f ? `${f.best_r.aic ?? '–'} / ${f.best_r.bic ?? '–'}`
                    : '–'),
                h('td', { class: 'num' }, f ? fmt(f.f_value) : '–'),
                h('td', { class: 'num' }, f ? fmt(f.p_value, 3) : '–'),
                h('td', {}, !f?.calibration ? '–' : f.calibration.current ? 'current'
                    : 'stored only'),
                h('td', {}, fmtTime(j.created_ms)));
        });
        fill(fitTable, h('table', { class: 'list', 'data-testid': 'fit-jobs' },
            h('thead', {}, h('tr', {}, ['Job', 'Pixel (dcol, drow)', 'State', 'Result',
                'Best r (AIC / BIC)', 'F', 'p', 'Calibration', 'Queued']
                .map((t) => h('th', { scope: 'col' }, t)))),
            h('tbody', {}, rows.length ? rows : h('tr', {}, h('td', { colspan: 9, class: 'empty' },
                'No fit yet: the automatic fit starts when the scan is done.')))));
    }

    // The form to fit another pixel, built once (a re-read of the fits keeps what was typed).
    async function loadFitForm() {
        const rule = await requestRules('post', '/api/scans/{id}/fits');
        fill(fitFormBox, buildFitForm(rule, scan, async (reply) => {
            ctx.announce(`Fit job #${reply.job.id} queued`);
            await loadFits();
        }));
    }

    function queueFits() {
        clearTimeout(fitsTimer);
        fitsTimer = setTimeout(() => !closed && loadFits().then(loadOverview).catch(() => {}),
            300);
    }

    const stop = ctx.onJob((ev) => {
        if (ev.scan_id !== id) return;
        if (ev.kind === 'fit') {
            queueFits();
            return;
        }
        if (!scan) return;
        const was = scan.state;
        Object.assign(scan, { state: ev.state, progress: ev.progress,
            points_done: ev.points_done });
        const cell = summary.querySelector('td.progress');
        if (cell) setProgress(cell, { ...scan, eta_s: ev.eta_s, phase: ev.phase });
        if (was !== ev.state) {
            loadScan().catch(() => {});
            if (!ACTIVE.has(ev.state)) loadRaster().then(loadOverview);
        } else if (Date.now() - rasterAt > 3000) {
            loadRaster(false); // the raster fills in while the scan runs
        }
    });
    // events can be missed: while the scan or its fits are active, re-read them every few s
    const poll = setInterval(() => {
        if (closed || !scan) return;
        if (ACTIVE.has(scan.state)) loadScan().then(() => !ACTIVE.has(scan.state) &&
            loadRaster().then(loadOverview))
            .catch(() => {});
        if (fits.querySelector('tr[data-state="queued"], tr[data-state="running"]')) queueFits();
    }, POLL_MS);
    loadScan().then(() => Promise.all([loadRaster().then(loadOverview), loadFits(),
        loadFitForm()]))
        .catch((err) => {
            root.append(failure(err));
            if (err instanceof ApiError && err.status === 404) head.textContent = `Scan #${id}`;
        });
    return () => {
        closed = true;
        purgeIn(root);
        clearInterval(poll);
        clearTimeout(fitsTimer);
        stop();
    };
}
