// calib.js: the lab's calibration database: a search across sensors (GET /api/calibrations with
// its filters; each row links to its CSV and to its pixel), and the Pixel view: the current IPS
// map of one sensor pixel (S, the interpolated surface, S_err: Plotly, µm axes) with its
// downloads (JSON, and CSV with positions in µm and the pitch), two maps compared side by side
// with their difference (calib_maps.js), and the pixel's history (GET .../calibration and
// .../history) as small multiples and a table: who made each map current, when and why, the map
// it superseded, and which map of its fit each is (recommended, shrunk or kriged: named in the
// current map's heading, figure and sentence on how it was made, and in every history row).
import { get } from './api.js';
import {
    clearError, errorBox, failure, field, fill, fmt, fmtTime, formBody, h, showError,
} from './dom.js';
import { cellSource, compareFigure, historyFigure, mapFigure, wienerSource } from './calib_maps.js';
import { purgeIn } from './charts.js';
import { errFigure, surfaceFigure } from './fit_maps.js';
import { kindTitle, mapSentence, storedMap } from './fit_stored.js';

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

// Which map of its fit a calibration holds (its `map`, database schema 7; kriged schema 8), the
// rms of its resolution error S_res where known (structure finer than the grid, beside S_err's
// noise), and its map_note (schema 9: why it is not the map its fit asked for) when it has one.
function mapWord(c) {
    const which = c.map === 'shrunk'
        ? `The shrunk map: r = ${c.r}'s detail shrunk toward r = ${c.r - 1} (fit request "map": ` +
          '"shrunk"; S_err includes the shrinkage\'s expected bias)'
        : c.map === 'kriged'
            ? `The kriged map on a fine ${c.r} × ${c.r} grid (fit request "map": "kriged"; a ` +
              'Gaussian-process estimate, closest to the truth in the fidelity harness; S_err ' +
              'is its whole error)'
            : `The recommended r's own least-squares map (r = ${c.r})`;
    const res = Array.isArray(c.S_res) && c.S_res.length
        ? Math.sqrt(c.S_res.reduce((a, v) => a + v * v, 0) / c.S_res.length) : null;
    const whole = res === null ? which : `${which}; resolution error S_res rms ${fmt(res, 3)} ` +
        '(add in quadrature to S_err)';
    return c.map_note ? `${whole}. ${c.map_note}` : whole;
}

// A calibration's map kind and grid in a few words: "kriged 24 × 24" (calibrations stored before
// schema 7 have no map: the recommended one).
const kindGrid = (c) => `${c.map || 'recommended'} ${c.r} × ${c.r}`;

// How the calibration's map was made, in the Fit view's sentence (fit_stored.js), from its fit's
// result: filled into el when the fit is read; left empty when it cannot be (no fit, or the fit's
// map of that kind is not on the calibration's grid).
async function howMade(el, cal) {
    if (!cal.fit_id) return;
    const f = await get(`/api/fits/${cal.fit_id}`);
    const res = f.result || {};
    const m = storedMap(res, cal.map || 'recommended');
    if (!m || m.r !== cal.r) return;
    el.textContent = `How it was made (fit #${cal.fit_id}): ${mapSentence(res, m)}`;
    el.hidden = false;
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
                        h('td', {}, h('a', { href: `#/sensors/${c.sensor_id}` },
                            s ? `${s.model} ${s.serial}` : `#${c.sensor_id}`)),
                        h('td', {}, h('a', { href: pixelHref(c) },
                            `(${c.pixel.col}, ${c.pixel.row})`)),
                        h('td', { title: mapWord(c) },
                            c.map === 'recommended' || !c.map ? c.r : `${c.r} ${c.map}`),
                    h('td', {}, c.status), h('td', {}, fmt(c.chi2_red)),
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

// ---- one pixel: current map, comparisons, history ----

// The calibration cal as CSV: one line per sub-pixel with its centre in µm and the pitch (the
// API's CSV has the indices only), and the resolution error S_res last (empty when not known);
// numbers as JavaScript prints them (shortest exact form).
export function calibrationCsv(cal, pitch) {
    const r = cal.r, w = pitch / r;
    const lines = ['calibration_id,sensor_id,pixel_col,pixel_row,r,pitch_um,i,j,x_um,y_um,S,S_err,' +
        'S_res'];
    for (let j = 0; j < r; j++) {
        for (let i = 0; i < r; i++) {
            const k = j * r + i;
            lines.push([cal.id, cal.sensor_id, cal.pixel.col, cal.pixel.row, r, pitch, i, j,
                (i + 0.5) * w, (j + 0.5) * w, cal.S[k], cal.S_err ? cal.S_err[k] : '',
                cal.S_res ? cal.S_res[k] : '']
                .map((v) => (v === null || v === undefined ? '' : String(v))).join(','));
        }
    }
    return `${lines.join('\n')}\n`;
}

// The calibration as JSON: the API's document with the pitch and the sub-pixel centres (µm).
export function calibrationJson(cal, pitch) {
    const c = Array.from({ length: cal.r }, (_, i) => (i + 0.5) * pitch / cal.r);
    return `${JSON.stringify({ ...cal, pitch_um: pitch, x_um: c, y_um: c }, null, 1)}\n`;
}

// A button that downloads text made on click as file name.
function downloadButton(label, name, type, make, testid) {
    return h('button', { type: 'button', class: 'small', 'data-testid': testid,
        onclick: () => {
            const url = URL.createObjectURL(new Blob([make()], { type }));
            const a = h('a', { href: url, download: name, hidden: true });
            document.body.append(a);
            a.click();
            a.remove();
            setTimeout(() => URL.revokeObjectURL(url), 60000);
        } }, label);
}

// The compare panel: two selects of map sources (this pixel's calibrations, the Wiener baseline
// of the current map's fit, any calibration added by its number) and their figure.
function comparePanel(hist, cur, pitch) {
    const w = pitch || 1;
    const options = new Map(); // value -> {label, load: () => source}
    const date = (ms) => fmtTime(ms).slice(0, 16);
    const addCal = (c, extra = '') => options.set(`cal:${c.id}`, { label: `#${c.id}${extra}, ` +
        `${kindGrid(c)}, ${date(c.created_ms)}${c.current ? ' (current)' : ''}`,
    load: async () => cellSource(`#${c.id} (r = ${c.r})`, c.S, c.r, w, c.S_err) });
    for (const c of hist.items) addCal(c);
    if (cur.fit_id) {
        options.set(`wiener:${cur.fit_id}`, { label: `Wiener baseline of fit #${cur.fit_id} ` +
            `(the current map's)`, load: async () => {
            const f = await get(`/api/fits/${cur.fit_id}`);
            const wn = f.result?.wiener;
            if (!wn || wn.error || !Array.isArray(wn.S)) {
                throw new Error(`fit #${cur.fit_id} has no Wiener baseline`);
            }
            return wienerSource(`Wiener of fit #${cur.fit_id}`, wn);
        } });
    }
    const sel = (id, label) => h('label', { class: 'fld', for: id }, h('span', { class: 'lbl' },
        label), h('select', { id, 'data-testid': id, style: 'min-width: 14rem; max-width: 100%' }));
    const selA = sel('cmp-a', 'Map A'), selB = sel('cmp-b', 'Map B');
    const fillSel = (lab, value) => {
        const s = lab.querySelector('select'), keep = value ?? s.value;
        fill(s, [...options].map(([v, o]) => h('option', { value: v }, o.label)));
        s.value = keep;
    };
    const other = h('input', { type: 'number', min: 1, 'data-field': 'id', id: 'cmp-other',
        inputmode: 'numeric' });
    const err = errorBox();
    const addForm = h('form', { class: 'inline-form', novalidate: true, 'data-testid': 'cmp-add',
        'aria-label': 'Add a calibration to compare' },
    h('div', { class: 'row-many' }, h('label', { class: 'fld', for: 'cmp-other' },
        h('span', { class: 'lbl' }, 'Another calibration (#, e.g. of another pixel)'), other),
    h('button', { type: 'submit' }, 'Add')), err);
    const out = h('div', { class: 'pfig-slot', 'data-testid': 'compare-out' });
    const draw = async () => {
        purgeIn(out);
        const oa = options.get(selA.querySelector('select').value);
        const ob = options.get(selB.querySelector('select').value);
        if (!oa || !ob) return;
        try {
            const [a, b] = await Promise.all([oa.load(), ob.load()]);
            fill(out, compareFigure(a, b, pitch).fig);
        } catch (ex) {
            fill(out, failure(ex));
        }
    };
    addForm.addEventListener('submit', async (e) => {
        e.preventDefault();
        clearError(addForm);
        try {
            const id = Number(other.value);
            if (!Number.isInteger(id) || id < 1) {
                throw Object.assign(new Error('a calibration number is a positive integer'),
                    { field: 'id' });
            }
            const c = await get(`/api/calibrations/${id}`);
            addCal(c, ` of pixel (${c.pixel.col}, ${c.pixel.row})` +
                (c.sensor_id !== cur.sensor_id ? ` of sensor #${c.sensor_id}` : ''));
            fillSel(selA);
            fillSel(selB, `cal:${c.id}`);
            await draw();
        } catch (ex) {
            showError(addForm, ex);
        }
    });
    fillSel(selA, `cal:${cur.id}`);
    const prev = hist.items.find((c) => c.id !== cur.id);
    fillSel(selB, prev ? `cal:${prev.id}` : cur.fit_id ? `wiener:${cur.fit_id}` : `cal:${cur.id}`);
    selA.querySelector('select').addEventListener('change', draw);
    selB.querySelector('select').addEventListener('change', draw);
    draw();
    return [h('div', { class: 'row-many' }, selA, selB), addForm, out];
}

export function renderPixel(root, sensorId, col, row) {
    const base = `/api/sensors/${sensorId}/pixels/${col}/${row}`;
    fill(root, h('p', { class: 'muted' }, 'Loading…'));
    (async () => {
        const sensor = await get(`/api/sensors/${sensorId}`);
        const pitch = sensor.pitch_um;
        const title = [h('p', { class: 'crumbs' },
            h('a', { href: `#/calibrations?sensor=${sensorId}` }, '← Calibrations'), ' · ',
            h('a', { href: `#/sensors/${sensorId}` }, 'the sensor and its photon transfer')),
        h('h2', {}, `Pixel (${col}, ${row}) of ${sensor.model} ${sensor.serial}`)];
        let cur;
        try {
            cur = await get(`${base}/calibration`);
        } catch (ex) {
            fill(root, ...title, failure(ex));
            return;
        }
        const hist = await get(`${base}/history`);
        const kind = cur.map || 'recommended';
        const how = h('p', { class: 'sub', 'data-testid': 'current-how', hidden: true });
        howMade(how, cur).catch(() => {});
        purgeIn(root);
        fill(root, ...title,
            h('section', { class: 'panel', 'aria-labelledby': 'cur-h' },
                h('h3', { id: 'cur-h' }, `Current calibration #${cur.id}: the `,
                    h('span', { 'data-testid': 'current-kind', dataset: { map: kind } }, kind),
                    ` map, ${cur.r} × ${cur.r}`),
                h('p', { class: 'sub' }, `r = ${cur.r}, status ${cur.status}, χ²/dof ` +
                    `${fmt(cur.chi2_red)}, I₀ = ${fmt(cur.I0, 6)} DN, ` +
                    `${cur.noise_model} noise, ` +
                    `λ = ${fmt(cur.optics.wavelength_nm)} nm, NA = ${fmt(cur.optics.na)}, ` +
                    `ipsd ${cur.software_version} · ${fmtTime(cur.created_ms)} · from `,
                provenance(cur)),
                h('p', { class: 'sub', 'data-testid': 'current-map' }, mapWord(cur)),
                cur.map_note ? h('p', { class: 'sub', 'data-testid': 'current-map-note' },
                    cur.map_note) : null, how,
                h('p', { class: 'sub', 'data-testid': 'current-why' }, `Made current by ` +
                    `${cur.by ?? '–'}: ${cur.reason ?? '–'}`, cur.supersedes
                    ? ` (replaced #${cur.supersedes})` : ''),
                h('p', { class: 'downloads' }, 'Download: ',
                    downloadButton('JSON', `calibration-${cur.id}.json`, 'application/json',
                        () => calibrationJson(cur, pitch), 'download-json'), ' ',
                    downloadButton('CSV (µm)', `calibration-${cur.id}-um.csv`, 'text/csv',
                        () => calibrationCsv(cur, pitch), 'download-csv'), ' · ',
                    csvLink(cur, 'the API\'s CSV'), ' · ',
                    h('a', { href: `/api/calibrations/${cur.id}/map.fits`,
                        download: `calibration-${cur.id}.fits`, 'data-testid': 'download-fits',
                        title: 'S and S_err as FITS image extensions with their sampling, optics ' +
                            'and provenance (docs/api.md, FITS)' }, 'FITS'), ' · ',
                    h('a', { href: `/api/sensors/${sensorId}/calibrations.fits`,
                        download: `sensor-${sensorId}-calibrations.fits` },
                    'every current map of the sensor as FITS'), h('span', { class: 'muted small' },
                        ` (positions in µm from the pixel's top-left corner, y downward; ` +
                        `pitch ${fmt(pitch)} µm)`)),
                h('div', { class: 'maps' },
                    mapFigure(cellSource('current', cur.S, cur.r, pitch, cur.S_err), pitch,
                        'plot-cal-S', `${kindTitle(kind)} S (${cur.r}×${cur.r})`),
                    surfaceFigure(`/api/calibrations/${cur.id}/interp`, pitch),
                    cur.S_err ? errFigure(cur, pitch) : null)),
            h('section', { class: 'panel', 'aria-labelledby': 'cmp-h' },
                h('h3', { id: 'cmp-h' }, 'Compare two maps'),
                h('p', { class: 'muted small' }, 'Two dates of this pixel, another pixel\'s ' +
                    'calibration, or the forward-model map against the Wiener baseline; A and B ' +
                    'on one colour scale, and A − B.'),
                comparePanel(hist, cur, pitch)),
            h('section', { class: 'panel', 'aria-labelledby': 'hist-h' },
                h('h3', { id: 'hist-h' }, `History (${hist.items.length})`),
                hist.items.length ? historyFigure(hist.items, pitch) : null,
                h('p', {}, h('a', { href: `${base}/history?format=csv`,
                    download: `pixel-${sensorId}-${col}-${row}-history.csv` }, 'history as CSV')),
                h('div', { class: 'table-wrap' }, h('table', { class: 'list',
                    'data-testid': 'history-table' },
                h('thead', {}, h('tr', {}, ['#', 'r', 'Map', 'Status', 'χ²/dof',
                    'Made current', 'By', 'Why', 'Replaced', 'State', 'From', '']
                    .map((t) => h('th', { scope: 'col' }, t)))),
                h('tbody', {}, hist.items.map((c) => h('tr',
                    { class: c.current ? 'current' : null },
                    h('td', {}, c.id),
                    h('td', {}, c.r), h('td', { 'data-testid': 'history-map', title: mapWord(c) },
                        c.map || 'recommended'),
                    h('td', {}, c.status), h('td', {}, fmt(c.chi2_red)),
                    h('td', {}, fmtTime(c.created_ms)), h('td', {}, c.by ?? '–'),
                    h('td', { class: 'small' }, c.reason ?? '–'),
                    h('td', {}, c.supersedes ? `#${c.supersedes}` : '–'),
                    h('td', {}, c.current ? 'current' : `superseded by #${c.superseded_by}`),
                    h('td', {}, provenance(c)), h('td', {}, csvLink(c)))))))));
    })().catch((err) => fill(root, failure(err)));
    return () => purgeIn(root);
}
