// scans.js: the Scans view (the list with live progress from /api/events, cancel buttons, the
// form for a new simulated scan and a new sensor) and the Scan detail view (state, the POI's
// response raster as a heatmap, the scan's fit jobs and fits, and a form to fit another pixel).
import { ApiError, get, post } from './api.js';
import {
    clearError, errorBox, failure, field, fill, fmt, fmtDuration, fmtTime, formBody, h, showError,
    stateBadge,
} from './dom.js';
import { heatmap } from './plots.js';

const ACTIVE = new Set(['queued', 'running']);
const POLL_MS = 5000; // re-read active scans now and then: events can be missed or damaged

function sensorName(s) {
    return s ? `#${s.id} ${s.model} ${s.serial}` : '?';
}

function progressCell(p) {
    const bar = h('progress', { max: 1, value: p.progress ?? 0 });
    const text = h('span', { class: 'prog-text' });
    const cell = h('td', { class: 'progress' }, bar, text);
    setProgress(cell, p);
    return cell;
}

// Updates a progress cell from a scan or a job event {state, progress, points_done,
// points_total, eta_s}.
function setProgress(cell, p) {
    const bar = cell.querySelector('progress'), text = cell.querySelector('.prog-text');
    bar.value = p.progress ?? 0;
    const pct = Math.round(100 * (p.progress ?? 0));
    bar.setAttribute('aria-label', `${pct} % done`);
    let s = `${p.points_done ?? 0} / ${p.points_total ?? p.raster?.points_total ?? '?'}`;
    if (p.state === 'running' && Number.isFinite(p.eta_s)) s += ` · ETA ${fmtDuration(p.eta_s)}`;
    else if (p.state === 'running' && p.phase && p.phase !== 'raster') s += ` · ${p.phase}`;
    text.textContent = s;
}

// ---- the Scans view ----

export function renderScans(root, ctx) {
    let sensors = [], scans = [], fitJobs = new Map(), timer = null, closed = false;
    let frame = 0, reloading = null;
    const pending = new Map(); // scan id -> its latest event not drawn yet
    const live = new Map(); // scan id -> the last event (ETA, phase)
    const tableMsg = errorBox();
    const tbody = h('tbody');
    const table = h('table', { class: 'list', 'data-testid': 'scan-table' },
        h('caption', { class: 'sr-only' }, 'Scans, newest first'),
        h('thead', {}, h('tr', {}, ['Scan', 'State', 'Progress', 'POI (col, row)', 'Sensor',
            'Created', 'Auto fit', ''].map((t) => h('th', { scope: 'col' }, t)))), tbody);
    const sensorSelect = h('select', { id: 'scan-sensor', 'data-field': 'sensor_id',
        'data-type': 'int', required: true });
    const sensorForm = buildSensorForm(async (s) => {
        await loadSensors();
        sensorSelect.value = String(s.id);
    });
    const scanForm = buildScanForm(sensorSelect, async (reply) => {
        await loadScans();
        ctx.announce(`Scan #${reply.scan.id} queued (job #${reply.job?.id ?? '?'})`);
    });
    fill(root, h('div', { class: 'two-col' },
        h('section', { class: 'col-main', 'aria-labelledby': 'scans-h' },
            h('h2', { id: 'scans-h' }, 'Scans'),
            h('div', { class: 'table-msg' }, tableMsg), h('div', { class: 'table-wrap' }, table)),
        h('aside', { class: 'col-side panel', 'aria-labelledby': 'new-scan-h' },
            h('h2', { id: 'new-scan-h' }, 'New simulated scan'), sensorForm, scanForm)));

    async function loadSensors() {
        const page = await get('/api/sensors?limit=1000');
        sensors = page.items;
        const keep = sensorSelect.value;
        fill(sensorSelect,
            h('option', { value: '' }, sensors.length ? 'Choose a sensor'
                : 'No sensor yet: create one'),
            sensors.map((s) => h('option', { value: s.id },
                `${sensorName(s)} (${s.n_cols}×${s.n_rows}, ${fmt(s.pitch_um)} µm)`)));
        if (keep && sensors.some((s) => String(s.id) === keep)) sensorSelect.value = keep;
        else if (sensors.length) sensorSelect.value = String(sensors[sensors.length - 1].id);
    }

    async function loadScans() {
        const [page, jobs] = await Promise.all([get('/api/scans?limit=100'),
            get('/api/jobs?kind=fit&limit=1000')]);
        scans = page.items;
        fitJobs = new Map();
        for (const j of jobs.items) { // newest first: keep the first (latest) per scan
            if (j.scan_id && !fitJobs.has(j.scan_id)) fitJobs.set(j.scan_id, j);
        }
        drawRows();
        schedulePoll();
    }

    // Rebuilds only the rows whose state changed, so a button under the pointer stays put.
    function drawRows() {
        const byId = new Map(sensors.map((s) => [s.id, s]));
        if (!scans.length) {
            fill(tbody, h('tr', {}, h('td', { colspan: 8, class: 'empty' },
                'No scans yet. Start one with the form.')));
            return;
        }
        const old = new Map([...tbody.querySelectorAll('tr[data-scan-id]')]
            .map((r) => [Number(r.dataset.scanId), r]));
        const rows = scans.map((sc) => {
            const r = old.get(sc.id);
            if (!r || r.dataset.key !== rowKey(sc)) return scanRow(sc, byId.get(sc.sensor_id));
            setProgress(r.querySelector('td.progress'), { ...sc, eta_s: live.get(sc.id)?.eta_s,
                phase: live.get(sc.id)?.phase });
            return r;
        });
        const same = rows.length === tbody.children.length &&
            rows.every((r, i) => tbody.children[i] === r);
        if (!same) fill(tbody, ...rows);
    }

    function rowKey(sc) {
        const f = fitJobs.get(sc.id);
        return `${sc.state}|${f?.state ?? ''}|${f?.fit_id ?? ''}`;
    }

    function scanRow(sc, sensor) {
        const ev = live.get(sc.id);
        const p = { ...sc, eta_s: ev?.eta_s, phase: ev?.phase };
        return h('tr', { dataset: { scanId: sc.id, state: sc.state, key: rowKey(sc) } },
            h('td', {}, h('a', { href: `#/scans/${sc.id}` }, `#${sc.id}`)),
            h('td', { class: 'st' }, stateBadge(sc.state)),
            progressCell(p),
            h('td', {}, `(${sc.poi.col}, ${sc.poi.row})`),
            h('td', {}, sensorName(sensor)),
            h('td', {}, fmtTime(sc.created_ms)),
            h('td', { class: 'fit' }, fitCell(fitJobs.get(sc.id))),
            h('td', { class: 'act' }, ACTIVE.has(sc.state) ? cancelButton(sc.id) : null));
    }

    function fitCell(job) {
        if (!job) return '–';
        if (job.fit_id) return h('a', { href: `#/fits/${job.fit_id}` }, `fit #${job.fit_id}`);
        return stateBadge(job.state);
    }

    function cancelButton(id) {
        return h('button', { type: 'button', class: 'small', 'aria-label': `Cancel scan #${id}`,
            onclick: async (e) => {
                e.target.disabled = true;
                try {
                    await post(`/api/scans/${id}/cancel`);
                    clearError(tableMsg.parentElement);
                    await loadScans();
                } catch (err) {
                    showError(tableMsg.parentElement, err);
                    e.target.disabled = false;
                }
            } }, 'Cancel');
    }

    // Scan events come by the hundred per second: keep the last per scan, draw once a frame.
    function onJob(ev) {
        if (ev.kind === 'fit' && ev.scan_id) {
            const was = fitJobs.get(ev.scan_id);
            if (was?.state === ev.state && was?.fit_id === ev.fit_id) return;
            fitJobs.set(ev.scan_id, { ...ev });
            const cell = tbody.querySelector(`tr[data-scan-id="${ev.scan_id}"] td.fit`);
            if (cell) fill(cell, fitCell(ev));
            return;
        }
        if (ev.kind !== 'scan' || !ev.scan_id) return;
        live.set(ev.scan_id, ev);
        pending.set(ev.scan_id, ev);
        if (!frame) frame = requestAnimationFrame(flush);
    }

    function flush() {
        frame = 0;
        for (const ev of pending.values()) applyScanEvent(ev);
        pending.clear();
    }

    function applyScanEvent(ev) {
        const sc = scans.find((s) => s.id === ev.scan_id);
        if (!sc) {
            reload(); // a scan queued elsewhere
            return;
        }
        const changed = sc.state !== ev.state;
        Object.assign(sc, { state: ev.state, progress: ev.progress, points_done: ev.points_done });
        const row = tbody.querySelector(`tr[data-scan-id="${ev.scan_id}"]`);
        if (!row) return;
        setProgress(row.querySelector('td.progress'), { ...sc, eta_s: ev.eta_s, phase: ev.phase });
        if (!changed) return;
        row.dataset.state = ev.state;
        row.dataset.key = rowKey(sc);
        fill(row.querySelector('td.st'), stateBadge(ev.state));
        fill(row.querySelector('td.act'), ACTIVE.has(ev.state) ? cancelButton(sc.id) : null);
    }

    function reload() {
        reloading ??= loadScans().catch(() => {}).finally(() => { reloading = null; });
        return reloading;
    }

    function schedulePoll() {
        clearTimeout(timer);
        const busy = (s) => ACTIVE.has(s.state) || ACTIVE.has(fitJobs.get(s.id)?.state);
        if (!closed && scans.some(busy)) {
            timer = setTimeout(reload, POLL_MS);
        }
    }

    const stop = ctx.onJob(onJob);
    loadSensors().then(loadScans).catch((err) => root.append(failure(err)));
    return () => {
        closed = true;
        clearTimeout(timer);
        cancelAnimationFrame(frame);
        stop();
    };
}

// The "new sensor" form (inside a <details>); onCreated(sensor) after a 201.
function buildSensorForm(onCreated) {
    const err = errorBox();
    const form = h('form', { class: 'stack', novalidate: true, 'aria-label': 'New sensor',
        'data-testid': 'sensor-form' },
    h('div', { class: 'row2' },
        field('Model', { 'data-field': 'model', placeholder: 'e.g. IMX290', required: true }),
        field('Serial', { 'data-field': 'serial', placeholder: 'e.g. SN-0001', required: true })),
    h('div', { class: 'row3' },
        field('Columns', { 'data-field': 'n_cols', 'data-type': 'int', type: 'number',
            value: 256 }),
        field('Rows', { 'data-field': 'n_rows', 'data-type': 'int', type: 'number', value: 256 }),
        field('Pitch (µm)', { 'data-field': 'pitch_um', 'data-type': 'num', type: 'number',
            step: 'any', value: 6 })),
    h('div', { class: 'row2' },
        field('Gain (e⁻/DN)', { 'data-field': 'gain_e_per_dn', 'data-type': 'num',
            type: 'number', step: 'any', placeholder: '3.153' }),
        field('Read noise (e⁻)', { 'data-field': 'read_noise_e', 'data-type': 'num',
            type: 'number', step: 'any', placeholder: '5.67' })),
    h('div', { class: 'row2' },
        field('Bias (DN)', { 'data-field': 'bias_dn', 'data-type': 'num', type: 'number',
            step: 'any', placeholder: '100' }),
        field('Full scale (DN)', { 'data-field': 'full_scale_dn', 'data-type': 'num',
            type: 'number', step: 'any', placeholder: '16383' })),
    err,
    h('button', { type: 'submit' }, 'Create sensor'));
    const details = h('details', { class: 'new-sensor' }, h('summary', {}, 'New sensor…'), form);
    form.addEventListener('submit', async (e) => {
        e.preventDefault();
        clearError(form);
        const btn = form.querySelector('button[type=submit]');
        btn.disabled = true;
        try {
            const s = await post('/api/sensors', formBody(form));
            details.open = false;
            form.reset();
            await onCreated(s);
        } catch (ex) {
            showError(form, ex);
        } finally {
            btn.disabled = false;
        }
    });
    return details;
}

// The scan request form; onQueued(reply) after a 202.
function buildScanForm(sensorSelect, onQueued) {
    const err = errorBox();
    const num = (label, f, attrs = {}) => field(label, { 'data-field': f, 'data-type': 'num',
        type: 'number', step: 'any', ...attrs });
    const int = (label, f, attrs = {}) => field(label, { 'data-field': f, 'data-type': 'int',
        type: 'number', step: 1, ...attrs });
    const wl = num('Wavelength (nm)', 'optics.wavelength_nm', { value: 550 });
    const na = num('NA', 'optics.na', { value: 0.25 });
    const radius = num('Spot radius (µm)', 'optics.spot_radius_um', { disabled: true,
        placeholder: '1.342' });
    const mode = (m) => {
        na.querySelector('input').disabled = m !== 'na';
        radius.querySelector('input').disabled = m !== 'radius';
    };
    const radio = (value, label, checked) => h('label', { class: 'inline' },
        h('input', { type: 'radio', name: 'optics-mode', value, checked,
            onchange: () => mode(value) }), ` ${label}`);
    const form = h('form', { class: 'stack', novalidate: true, 'data-testid': 'scan-form',
        'aria-labelledby': 'new-scan-h' },
    h('label', { class: 'fld', for: 'scan-sensor' }, h('span', { class: 'lbl' }, 'Sensor'),
        sensorSelect),
    h('fieldset', {}, h('legend', {}, 'Pixel of interest'),
        h('div', { class: 'row2' }, int('Column', 'poi.col', { min: 0, required: true }),
            int('Row', 'poi.row', { min: 0, required: true }))),
    h('fieldset', {}, h('legend', {}, 'Optics'),
        h('div', { class: 'radios' }, radio('na', 'wavelength and NA', true),
            radio('radius', 'spot radius')),
        h('div', { class: 'row3' }, wl, na, radius)),
    h('fieldset', {}, h('legend', {}, 'Raster'),
        h('div', { class: 'row2' },
            int('Area (pixels, odd)', 'raster.area_px', { value: 5 }),
            num('Step (µm)', 'raster.step_um', { value: 0.6 })),
        h('div', { class: 'row2' },
            int('Sub-frame (pixels, odd)', 'raster.sub_px', { value: 9 }),
            int('Frames per point', 'raster.frames', { value: 12 }))),
    h('div', { class: 'row3' },
        h('label', { class: 'fld', for: 'scan-scene' }, h('span', { class: 'lbl' }, 'Scene'),
            h('select', { id: 'scan-scene', 'data-field': 'scene' },
                h('option', { value: 'paperlike', selected: true }, 'paperlike'),
                h('option', { value: 'uniform' }, 'uniform'))),
        num('Exposure (µs)', 'exposure_us', { placeholder: '10000' }),
        int('Seed', 'seed', { placeholder: '1' })),
    err,
    h('button', { type: 'submit', class: 'primary' }, 'Start scan'));
    form.addEventListener('submit', async (e) => {
        e.preventDefault();
        clearError(form);
        const btn = form.querySelector('button[type=submit]');
        btn.disabled = true;
        try {
            await onQueued(await post('/api/scans', formBody(form)));
        } catch (ex) {
            showError(form, ex);
        } finally {
            btn.disabled = false;
        }
    });
    return form;
}

// ---- the Scan detail view ----

export function renderScan(root, id, ctx) {
    let scan = null, closed = false, fitsTimer = null, rasterAt = 0;
    const head = h('h2', {}, `Scan #${id}`);
    const summary = h('section', { class: 'panel', 'aria-label': 'Scan summary' });
    const raster = h('section', { class: 'panel', 'aria-labelledby': 'raster-h' },
        h('h3', { id: 'raster-h' }, 'Response of the pixel of interest'));
    const fits = h('section', { class: 'panel', 'aria-labelledby': 'fits-h' },
        h('h3', { id: 'fits-h' }, 'Fits of this scan'));
    const headMsg = errorBox();
    fill(root, h('p', { class: 'crumbs' }, h('a', { href: '#/scans' }, '← Scans')),
        h('div', { class: 'title-row' }, head), h('div', {}, headMsg),
        h('div', { class: 'two-col even' }, summary, raster), fits);

    async function loadScan() {
        scan = await get(`/api/scans/${id}`);
        const sensor = await get(`/api/sensors/${scan.sensor_id}`).catch(() => null);
        drawHead();
        drawSummary(sensor);
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

    function drawSummary(sensor) {
        const s = scan, o = s.optics, r = s.raster;
        const rows = [
            ['Sensor', sensor ? `${sensorName(sensor)} (${sensor.n_cols}×${sensor.n_rows}, ` +
                `${fmt(sensor.pitch_um)} µm pitch)` : `#${s.sensor_id}`],
            ['Pixel of interest', `(${s.poi.col}, ${s.poi.row})`],
            ['Optics', `λ = ${fmt(o.wavelength_nm)} nm, NA = ${fmt(o.na)}, spot radius ` +
                `R = ${fmt(o.spot_radius_um)} µm`],
            ['Raster', `${r.area_px}×${r.area_px} pixels in ${fmt(r.step_um)} µm steps: ` +
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

    async function loadRaster() {
        rasterAt = Date.now();
        let data;
        try {
            data = await get(`/api/scans/${id}/pixels/0/0?all=1`);
        } catch (err) {
            fill(raster, raster.firstChild, failure(err));
            return;
        }
        fill(raster, raster.firstChild, rasterFigure(data, scan && data.inside_only === 0 ? {
            n: scan.raster.points_per_axis, step: scan.raster.step_um } : null));
    }

    async function loadFits() {
        const [jobs, list] = await Promise.all([get(`/api/jobs?scan=${id}&kind=fit&limit=100`),
            get(`/api/scans/${id}/fits?limit=100`)]);
        const byFit = new Map(list.items.map((f) => [f.id, f]));
        const rows = jobs.items.map((j) => {
            const f = j.fit_id ? byFit.get(j.fit_id) : null;
            const px = j.params || {};
            return h('tr', { dataset: { jobId: j.id, state: j.state } },
                h('td', {}, `#${j.id}`), h('td', {}, `(${px.dcol ?? 0}, ${px.drow ?? 0})`),
                h('td', {}, stateBadge(j.state), j.error ? h('div', { class: 'err' }, j.error)
                    : null),
                h('td', {}, f ? h('a', { href: `#/fits/${f.id}`, 'data-testid': 'fit-link' },
                    `Fit #${f.id}`) : '–'),
                h('td', { class: 'num' }, f ? `${f.best_r.aic ?? '–'} / ${f.best_r.bic ?? '–'}`
                    : '–'),
                h('td', { class: 'num' }, f ? fmt(f.f_value) : '–'),
                h('td', { class: 'num' }, f ? fmt(f.p_value, 3) : '–'),
                h('td', {}, fmtTime(j.created_ms)));
        });
        const table = h('table', { class: 'list', 'data-testid': 'fit-jobs' },
            h('thead', {}, h('tr', {}, ['Job', 'Pixel (dcol, drow)', 'State', 'Result',
                'Best r (AIC / BIC)', 'F', 'p', 'Queued']
                .map((t) => h('th', { scope: 'col' }, t)))),
            h('tbody', {}, rows.length ? rows : h('tr', {}, h('td', { colspan: 8, class: 'empty' },
                'No fit yet: the automatic fit starts when the scan is done.'))));
        fill(fits, fits.firstChild, table, fitForm());
    }

    function fitForm() {
        const err = errorBox();
        const int = (label, f, attrs = {}) => field(label, { 'data-field': f, 'data-type': 'int',
            type: 'number', step: 1, ...attrs });
        const h2 = scan ? Math.floor(scan.raster.sub_px / 2) : 0;
        const form = h('form', { class: 'inline-form', novalidate: true,
            'aria-label': 'Fit a pixel of this scan' },
        h('h4', {}, 'Fit a pixel of the sub-frame'),
        h('div', { class: 'row-many' },
            int('dcol', 'dcol', { value: 0, min: -h2, max: h2 }),
            int('drow', 'drow', { value: 0, min: -h2, max: h2 }),
            int('r min', 'r_min', { value: 1 }), int('r max', 'r_max', { value: 8 }),
            h('label', { class: 'fld' }, h('span', { class: 'lbl' }, 'σ model'),
                h('select', { 'data-field': 'sigma' }, h('option', { value: 'paper' }, 'paper'),
                    h('option', { value: 'shot+read' }, 'shot+read'))),
            field('F-test edges', { 'data-field': 'ftest', value: 'top,left,bottom' }),
            int('F-test r', 'ftest_r', { value: 7 }),
            h('label', { class: 'fld check' }, h('input', { type: 'checkbox', checked: true,
                'data-field': 'wiener', 'data-type': 'bool' }), ' Wiener baseline')),
        err, h('button', { type: 'submit' }, 'Queue fit'));
        form.addEventListener('submit', async (e) => {
            e.preventDefault();
            clearError(form);
            try {
                const reply = await post(`/api/scans/${id}/fits`, formBody(form));
                ctx.announce(`Fit job #${reply.job.id} queued`);
                await loadFits();
            } catch (ex) {
                showError(form, ex);
            }
        });
        return form;
    }

    function queueFits() {
        clearTimeout(fitsTimer);
        fitsTimer = setTimeout(() => !closed && loadFits().catch(() => {}), 300);
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
            if (!ACTIVE.has(ev.state)) loadRaster();
        } else if (Date.now() - rasterAt > 3000) {
            loadRaster(); // the raster fills in while the scan runs
        }
    });
    // events can be missed: while the scan or its fits are active, re-read them every few s
    const poll = setInterval(() => {
        if (closed || !scan) return;
        if (ACTIVE.has(scan.state)) loadScan().then(() => !ACTIVE.has(scan.state) && loadRaster())
            .catch(() => {});
        if (fits.querySelector('tr[data-state="queued"], tr[data-state="running"]')) queueFits();
    }, POLL_MS);
    loadScan().then(() => Promise.all([loadRaster(), loadFits()]))
        .catch((err) => {
            root.append(failure(err));
            if (err instanceof ApiError && err.status === 404) head.textContent = `Scan #${id}`;
        });
    return () => {
        closed = true;
        clearInterval(poll);
        clearTimeout(fitsTimer);
        stop();
    };
}

// The response raster of a pixel (scan-file JSON) as a heatmap over the spot positions, with the
// pixel's outline [0, pitch] x [0, pitch]. grid {n, step}: the scan's whole raster (n x n points
// centred on the pixel), so a running scan shows its empty part too; without it (or when the
// points are not on it) the grid is the distinct positions present.
export function rasterFigure(data, grid) {
    if (!data.x_um.length) return h('p', { class: 'muted' }, 'No points stored yet.');
    const pitch = data.pitch_um;
    const axes = (grid && onGrid(data, grid, pitch)) || distinctAxes(data);
    const { xs, ys } = axes, nx = xs.length, ny = ys.length;
    const values = new Float64Array(nx * ny).fill(NaN);
    data.signal_dn.forEach((v, k) => {
        values[axes.row(data.y_um[k]) * nx + axes.col(data.x_um[k])] = v;
    });
    const x0 = xs[0], y0 = ys[0];
    const dx = nx > 1 ? (xs[nx - 1] - x0) / (nx - 1) : 1;
    const dy = ny > 1 ? (ys[ny - 1] - y0) / (ny - 1) : 1;
    return heatmap({
        values, nx, ny, size: 300, unit: 'DN', testid: 'raster-map',
        title: `Pixel (${data.pixel.col}, ${data.pixel.row}): mean signal (DN) against spot ` +
            `position, ${data.x_um.length} of ${nx * ny} points`,
        describe: (i, j, v) => `spot at x = ${fmt(xs[i])} µm, y = ${fmt(ys[j])} µm: ` +
            (Number.isFinite(v) ? `${fmt(v, 6)} DN` : 'not measured (yet)'),
        outline: (ctx, w, hh) => { // the pixel's edges, in canvas units
            const X = (x) => (x - (x0 - dx / 2)) / (nx * dx) * w;
            const Y = (y) => (y - (y0 - dy / 2)) / (ny * dy) * hh;
            ctx.strokeStyle = '#ffffff';
            ctx.lineWidth = Math.max(1, w / 300);
            ctx.setLineDash([4, 3]);
            ctx.strokeRect(X(0), Y(0), X(pitch) - X(0), Y(pitch) - Y(0));
        },
    });
}

// The axes {xs, ys, col(x), row(y)} of the scan's n x n raster centred on the pixel, or null
// when the data's points are not on it.
function onGrid(data, grid, pitch) {
    const { n, step } = grid;
    if (!(n >= 1 && step > 0) || n > 2000) return null;
    const c = pitch / 2 - ((n - 1) / 2) * step;
    const axis = Array.from({ length: n }, (_, k) => c + k * step);
    const index = (v) => Math.round((v - c) / step);
    const fits = (v) => Math.abs((v - c) / step - index(v)) < 1e-3 && index(v) >= 0 &&
        index(v) < n;
    if (!data.x_um.every(fits) || !data.y_um.every(fits)) return null;
    return { xs: axis, ys: axis, col: index, row: index };
}

// The axes made of the distinct positions present (to 1e-6 um).
function distinctAxes(data) {
    const key = (v) => Math.round(v * 1e6);
    const axis = (a) => [...new Set(a.map(key))].sort((p, q) => p - q);
    const kx = axis(data.x_um), ky = axis(data.y_um);
    const ix = new Map(kx.map((v, i) => [v, i])), iy = new Map(ky.map((v, j) => [v, j]));
    return { xs: kx.map((v) => v / 1e6), ys: ky.map((v) => v / 1e6),
        col: (x) => ix.get(key(x)), row: (y) => iy.get(key(y)) };
}
