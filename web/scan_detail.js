// scan_detail.js: the Scan view (#/scans/ID): the scan's state and setup, the response raster of
// its pixel of interest (filling in while the scan runs), the fit jobs of the scan with their
// results, and the form to fit another pixel (fit_form.js). Live from /api/events, and re-read
// every few seconds while the scan or a fit is active.
import { ApiError, get, post } from './api.js';
import { errorBox, failure, fill, fmt, fmtTime, h, showError, stateBadge } from './dom.js';
import { buildFitForm } from './fit_form.js';
import { requestRules } from './rules.js';
import { rasterFigure } from './scan_plots.js';
import { ACTIVE, POLL_MS, progressCell, sensorName, setProgress } from './scan_state.js';

export function renderScan(root, id, ctx) {
    let scan = null, closed = false, fitsTimer = null, rasterAt = 0;
    const head = h('h2', {}, `Scan #${id}`);
    const summary = h('section', { class: 'panel', 'aria-label': 'Scan summary' });
    const raster = h('section', { class: 'panel', 'aria-labelledby': 'raster-h' },
        h('h3', { id: 'raster-h' }, 'Response of the pixel of interest'));
    const fitTable = h('div', {}), fitFormBox = h('div', {});
    const fits = h('section', { class: 'panel', 'aria-labelledby': 'fits-h' },
        h('h3', { id: 'fits-h' }, 'Fits of this scan'), fitTable, fitFormBox);
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
    loadScan().then(() => Promise.all([loadRaster(), loadFits(), loadFitForm()]))
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
