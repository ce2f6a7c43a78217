// calib.js: the lab's calibration database: a search across sensors (GET /api/calibrations with
// its filters; each row links to its CSV and to its pixel), and the Pixel view: the current IPS
// map of one sensor pixel and its history (GET .../calibration and .../history), each map with
// who made it current, when and why, and the map it superseded.
import { get } from './api.js';
import {
    clearError, errorBox, failure, field, fill, fmt, fmtTime, formBody, h, showError,
} from './dom.js';
import { mapFigures } from './maps.js';
import { heatmap } from './plots.js';

const LIMIT = 50;
const FILTERS = ['sensor', 'model', 'status', 'current', 'col_min', 'col_max', 'row_min',
    'row_max', 'since'];

function pixelHref(c) {
    return `#/sensors/${c.sensor_id}/pixels/${c.pixel.col}/${c.pixel.row}`;
}

function csvLink(c, label = 'CSV') {
    return h('a', { href: `/api/calibrations/${c.id}?format=csv`,
        download: `calibration-${c.id}.csv`, 'aria-label': `CSV of calibration #${c.id}` }, label);
}

function provenance(c) {
    return [c.scan_id ? h('a', { href: `#/scans/${c.scan_id}` }, `scan #${c.scan_id}`) : 'upload',
        c.fit_id ? [' / ', h('a', { href: `#/fits/${c.fit_id}` }, `fit #${c.fit_id}`)] : null];
}

// ---- search ----

export function renderCalibrations(root, params) {
    const err = errorBox();
    const sensorSel = h('select', { id: 'cal-sensor', 'data-field': 'sensor' },
        h('option', { value: '' }, 'any'));
    const current = h('input', { type: 'checkbox', id: 'cal-current',
        checked: params.get('current') !== '0' });
    const since = h('input', { type: 'date', id: 'cal-since' });
    const form = h('form', { class: 'search', novalidate: true, 'aria-label': 'Search calibrations',
        'data-testid': 'calib-form' },
    h('div', { class: 'row-many' },
        h('label', { class: 'fld', for: 'cal-sensor' }, h('span', { class: 'lbl' }, 'Sensor'),
            sensorSel),
        field('Model', { 'data-field': 'model', value: params.get('model') || '' }),
        field('Status', { 'data-field': 'status', value: params.get('status') || '',
            placeholder: 'e.g. ok' }),
        field('Columns from', { 'data-field': 'col_min', type: 'number',
            value: params.get('col_min') || '' }),
        field('to', { 'data-field': 'col_max', type: 'number',
            value: params.get('col_max') || '' }),
        field('Rows from', { 'data-field': 'row_min', type: 'number',
            value: params.get('row_min') || '' }),
        field('to', { 'data-field': 'row_max', type: 'number',
            value: params.get('row_max') || '' }),
        h('label', { class: 'fld', for: 'cal-since' }, h('span', { class: 'lbl' }, 'Since'), since),
        h('label', { class: 'fld check', for: 'cal-current' }, current, ' current only')),
    err, h('button', { type: 'submit' }, 'Search'));
    if (params.get('since')) since.valueAsNumber = Number(params.get('since'));
    const results = h('div', { class: 'results' });
    fill(root, h('h2', {}, 'Calibrations'), h('section', { class: 'panel' }, form),
        h('section', { class: 'panel', 'aria-label': 'Results' }, results));
    form.addEventListener('submit', (e) => {
        e.preventDefault();
        const q = new URLSearchParams();
        for (const [k, v] of Object.entries(formBody(form))) q.set(k, String(v));
        q.set('current', current.checked ? '1' : '0');
        if (since.value) q.set('since', String(since.valueAsNumber));
        const hash = `#/calibrations?${q}`;
        if (location.hash === hash) load();
        else location.hash = hash;
    });

    async function load() {
        clearError(form);
        const q = new URLSearchParams();
        for (const k of FILTERS) if (params.get(k)) q.set(k, params.get(k));
        if (!params.has('current')) q.set('current', '1');
        if (q.get('current') === '0') q.delete('current');
        const offset = Number(params.get('offset') || 0);
        q.set('limit', LIMIT);
        q.set('offset', offset);
        let page;
        try {
            page = await get(`/api/calibrations?${q}`);
        } catch (ex) {
            showError(form, ex);
            fill(results);
            return;
        }
        const sensors = new Map((await get('/api/sensors?limit=1000').catch(() => ({ items: [] })))
            .items.map((s) => [s.id, s]));
        const csvAll = new URLSearchParams(q);
        csvAll.set('format', 'csv');
        csvAll.set('limit', '1000');
        csvAll.set('offset', '0');
        const nav = (delta) => {
            const p = new URLSearchParams(params);
            p.set('offset', String(Math.max(0, offset + delta)));
            return `#/calibrations?${p}`;
        };
        fill(results,
            h('p', { class: 'sub' }, `${page.total} calibration${page.total === 1 ? '' : 's'}`,
                page.total ? [` · showing ${offset + 1}–${offset + page.items.length} · `,
                    h('a', { href: `/api/calibrations?${csvAll}`, download: 'calibrations.csv' },
                        'download these as CSV')] : null),
            page.items.length ? h('table', { class: 'list', 'data-testid': 'calib-table' },
                h('thead', {}, h('tr', {}, ['#', 'Sensor', 'Pixel', 'r', 'Status', 'χ²/dof',
                    'I₀ (DN)', 'Current', 'Created', 'From', '']
                    .map((t) => h('th', { scope: 'col' }, t)))),
                h('tbody', {}, page.items.map((c) => {
                    const s = sensors.get(c.sensor_id);
                    return h('tr', { dataset: { calibId: c.id } },
                        h('td', {}, c.id),
                        h('td', {}, s ? `${s.model} ${s.serial}` : `#${c.sensor_id}`),
                        h('td', {}, h('a', { href: pixelHref(c) },
                            `(${c.pixel.col}, ${c.pixel.row})`)),
                        h('td', {}, c.r), h('td', {}, c.status), h('td', {}, fmt(c.chi2_red)),
                        h('td', {}, fmt(c.I0, 6)),
                        h('td', {}, c.current ? 'yes' : `superseded by #${c.superseded_by}`),
                        h('td', {}, fmtTime(c.created_ms)), h('td', {}, provenance(c)),
                        h('td', {}, h('a', { href: pixelHref(c) }, 'map'), ' · ', csvLink(c)));
                }))) : h('p', { class: 'empty' }, 'No calibration matches.'),
            h('p', { class: 'pager' },
                offset > 0 ? h('a', { href: nav(-LIMIT) }, '← newer') : null, ' ',
                offset + page.items.length < page.total ? h('a', { href: nav(LIMIT) }, 'older →')
                    : null));
    }

    get('/api/sensors?limit=1000').then((p) => {
        sensorSel.append(...p.items.map((s) => h('option', { value: s.id },
            `#${s.id} ${s.model} ${s.serial}`)));
        sensorSel.value = params.get('sensor') || '';
    }).catch(() => {});
    load();
    return () => {};
}

// ---- one pixel: current map and history ----

export function renderPixel(root, sensorId, col, row) {
    const base = `/api/sensors/${sensorId}/pixels/${col}/${row}`;
    fill(root, h('p', { class: 'muted' }, 'Loading…'));
    (async () => {
        const sensor = await get(`/api/sensors/${sensorId}`);
        const title = [h('p', { class: 'crumbs' },
            h('a', { href: `#/calibrations?sensor=${sensorId}` }, '← Calibrations')),
        h('h2', {}, `Pixel (${col}, ${row}) of ${sensor.model} ${sensor.serial}`)];
        let cur;
        try {
            cur = await get(`${base}/calibration`);
        } catch (ex) {
            fill(root, ...title, failure(ex));
            return;
        }
        const hist = await get(`${base}/history`);
        fill(root, ...title,
            h('section', { class: 'panel', 'aria-labelledby': 'cur-h' },
                h('h3', { id: 'cur-h' }, `Current calibration #${cur.id}`),
                h('p', { class: 'sub' }, `r = ${cur.r}, status ${cur.status}, χ²/dof ` +
                    `${fmt(cur.chi2_red)}, I₀ = ${fmt(cur.I0, 6)} DN, ` +
                    `${cur.noise_model} noise, ` +
                    `λ = ${fmt(cur.optics.wavelength_nm)} nm, NA = ${fmt(cur.optics.na)}, ` +
                    `ipsd ${cur.software_version} · ${fmtTime(cur.created_ms)} · from `,
                provenance(cur), ' · ', csvLink(cur)),
                h('p', { class: 'sub', 'data-testid': 'current-why' }, `Made current by ` +
                    `${cur.by ?? '–'}: ${cur.reason ?? '–'}`, cur.supersedes
                    ? ` (replaced #${cur.supersedes})` : ''),
                h('div', { class: 'maps' }, mapFigures(cur.S, cur.S_err, cur.r,
                    sensor.pitch_um, `/api/calibrations/${cur.id}/interp`))),
            h('section', { class: 'panel', 'aria-labelledby': 'hist-h' },
                h('h3', { id: 'hist-h' }, `History (${hist.items.length})`),
                h('p', {}, h('a', { href: `${base}/history?format=csv`,
                    download: `pixel-${sensorId}-${col}-${row}-history.csv` }, 'history as CSV')),
                h('table', { class: 'list', 'data-testid': 'history-table' },
                    h('thead', {}, h('tr', {}, ['#', 'Map', 'r', 'Status', 'χ²/dof',
                        'Made current', 'By', 'Why', 'Replaced', 'State', 'From', '']
                        .map((t) => h('th', { scope: 'col' }, t)))),
                    h('tbody', {}, hist.items.map((c) => h('tr',
                        { class: c.current ? 'current' : null },
                        h('td', {}, c.id),
                        h('td', { class: 'thumb' }, heatmap({ values: c.S, nx: c.r, ny: c.r,
                            size: 48, title: `Calibration #${c.id}`, thumb: true })),
                        h('td', {}, c.r), h('td', {}, c.status), h('td', {}, fmt(c.chi2_red)),
                        h('td', {}, fmtTime(c.created_ms)), h('td', {}, c.by ?? '–'),
                        h('td', { class: 'small' }, c.reason ?? '–'),
                        h('td', {}, c.supersedes ? `#${c.supersedes}` : '–'),
                        h('td', {}, c.current ? 'current' : `superseded by #${c.superseded_by}`),
                        h('td', {}, provenance(c)), h('td', {}, csvLink(c))))))));
    })().catch((err) => fill(root, failure(err)));
    return () => {};
}
