// scans_list.js: the Scans view (#/scans): every scan with its state and live progress (from
// /api/events, and re-read every few seconds while any is active), its automatic fit, Cancel
// buttons; beside it the forms for a new sensor and a new simulated scan, built once the
// server's rules for them (rules.js) have arrived.
import { get, post } from './api.js';
import {
    clearError, errorBox, failure, fill, fmt, fmtTime, h, showError, stateBadge,
} from './dom.js';
import { requestRules } from './rules.js';
import { buildScanForm } from './scan_form.js';
import { ACTIVE, POLL_MS, progressCell, sensorName, setProgress } from './scan_state.js';
import { buildSensorForm } from './sensor_form.js';

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
    const newScanHead = h('h2', { id: 'new-scan-h' }, 'New simulated scan');
    const side = h('aside', { class: 'col-side panel', 'aria-labelledby': 'new-scan-h' },
        newScanHead, h('p', { class: 'muted' }, 'Loading the server\'s rules…'));
    fill(root, h('div', { class: 'two-col' },
        h('section', { class: 'col-main', 'aria-labelledby': 'scans-h' },
            h('h2', { id: 'scans-h' }, 'Scans'),
            h('div', { class: 'table-msg' }, tableMsg), h('div', { class: 'table-wrap' }, table)),
        side));
    Promise.all([requestRules('post', '/api/sensors'), requestRules('post', '/api/scans')])
        .then(([sensorRule, scanRule]) => fill(side, newScanHead,
            buildSensorForm(sensorRule, async (s) => {
                await loadSensors();
                sensorSelect.value = String(s.id);
                sensorSelect.dispatchEvent(new Event('change'));
            }),
            buildScanForm(scanRule, sensorSelect, async (reply) => {
                await loadScans();
                ctx.announce(`Scan #${reply.scan.id} queued (job #${reply.job?.id ?? '?'})`);
            })))
        .catch((err) => fill(side, newScanHead, failure(err)));

    async function loadSensors() {
        const page = await get('/api/sensors?limit=1000');
        sensors = page.items;
        const keep = sensorSelect.value;
        fill(sensorSelect,
            h('option', { value: '' }, sensors.length ? 'Choose a sensor'
                : 'No sensor yet: create one'),
            sensors.map((s) => h('option', { value: s.id, dataset: { cols: s.n_cols,
                rows: s.n_rows } },
                `${sensorName(s)} (${s.n_cols}×${s.n_rows}, ${fmt(s.pitch_um)} µm)`)));
        if (keep && sensors.some((s) => String(s.id) === keep)) sensorSelect.value = keep;
        else if (sensors.length) sensorSelect.value = String(sensors[sensors.length - 1].id);
        sensorSelect.dispatchEvent(new Event('change')); // the scan form presets the POI
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
            h('td', {}, h('a', { href: `#/scans/${sc.id}` }, `#${sc.id}`),
                sc.strategy?.kind === 'adaptive' // how the scan takes its points (docs/api.md)
                    ? h('span', { class: 'tag adaptive', title: 'adaptive scan' }, 'adaptive')
                    : null),
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
