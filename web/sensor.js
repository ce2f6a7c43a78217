// sensor.js: the Sensor view (#/sensors/ID): the sensor's constants, and its photon transfer
// (EMVA 1288): a "Measure photon transfer" button (POST /api/sensors/{id}/ptc), the
// job's progress from the event stream, the current measurement's figures (gain, read noise,
// dark signal, saturation, linearity range, with the gain's standard error), the photon-transfer
// plot (temporal variance against mean signal above the dark level, log-log, with the fitted line
// through the origin of slope K and the saturation point: Plotly) and the history of
// measurements (GET /api/sensors/{id}/ptc). The newest measurement's gain and read noise are
// what the sensor's fits use for sigma (docs/api.md).
import { get, post } from './api.js';
import { failure, fill, fmt, fmtTime, h, stateBadge } from './dom.js';
import { plotFigure, purgeIn } from './charts.js';

// The photon-transfer plot of a report: per level, x = mu - mu_dark (DN), y = sigma2 -
// sigma2_dark (DN^2) (EMVA 1288 R3.1 eq. 9: y = K x); the points of the gain fit, the others
// (beyond 70 % of saturation), the line y = K x over the data and the saturation level.
export function ptcFigure(doc) {
    const lv = doc.levels || [];
    const pts = lv.map((l, i) => ({ i, x: l.mu - l.mu_dark, y: l.sigma2 - l.sigma2_dark }))
        .filter((p) => p.x > 0 && p.y > 0); // a log axis shows positive values only
    const [lo, hi] = doc.fit_levels || [0, -1];
    const inFit = pts.filter((p) => p.i >= lo && p.i <= hi);
    const rest = pts.filter((p) => p.i < lo || p.i > hi);
    const xs = pts.map((p) => p.x);
    const x0 = Math.min(...xs), x1 = Math.max(...xs);
    const sat = pts.find((p) => p.i === doc.saturation_level);
    const hover = 'mean %{x:.4g} DN<br>variance %{y:.4g} DN²<extra></extra>';
    const data = [
        { type: 'scatter', mode: 'markers', name: 'levels in the gain fit',
            x: inFit.map((p) => p.x), y: inFit.map((p) => p.y),
            marker: { color: '#1f77b4', size: 7 }, hovertemplate: hover },
        { type: 'scatter', mode: 'markers', name: 'other levels', x: rest.map((p) => p.x),
            y: rest.map((p) => p.y), marker: { color: '#9aa4b2', size: 6, symbol: 'circle-open' },
            hovertemplate: hover },
        { type: 'scatter', mode: 'lines', name: `fit: σ² = K μ, K = ${fmt(doc.K, 5)} DN/e⁻`,
            x: [x0, x1], y: [doc.K * x0, doc.K * x1], line: { color: '#d62728', width: 1.5 },
            hoverinfo: 'skip' },
    ];
    if (sat) {
        data.push({ type: 'scatter', mode: 'markers', name: 'saturation', x: [sat.x], y: [sat.y],
            marker: { color: '#ff7f0e', size: 13, symbol: 'star' },
            hovertemplate: 'saturation: %{x:.5g} DN<extra></extra>' });
    }
    return plotFigure({
        title: 'Photon transfer: temporal variance against mean signal (both above the dark level)',
        testid: 'ptc-plot', name: 'photon-transfer', data,
        layout: { xaxis: { type: 'log', title: { text: 'mean signal μ − μ_dark (DN)' } },
            yaxis: { type: 'log', title: { text: 'variance σ² − σ²_dark (DN²)' } },
            legend: { orientation: 'h', y: -0.25 } },
        height: 400,
        note: 'Each point is a pair of flats and a pair of darks at one exposure (EMVA 1288). ' +
            'The slope of the line is the system gain K; the gain in e⁻/DN is 1/K.',
    });
}

// The figures of a measurement, one row each: label, value, and its raw number for tests.
function figures(m) {
    const doc = m.result || {};
    const lv = doc.levels || [];
    const sig = (i) => (lv[i] ? lv[i].mu - lv[i].mu_dark : NaN);
    const [a, b] = doc.linearity_levels || [];
    const pm = (v, e, n) => (e != null ? `${fmt(v, n)} ± ${fmt(e, 2)}` : fmt(v, n));
    const rows = [
        ['gain_e_per_dn', 'Conversion gain (e⁻/DN)', pm(m.gain_e_per_dn, m.gain_err_e_per_dn, 5),
            m.gain_e_per_dn],
        ['K', 'System gain K (DN/e⁻)', pm(doc.K, m.K_err, 5), doc.K],
        ['read_noise_e', 'Read noise (e⁻ rms)', fmt(m.read_noise_e, 4), m.read_noise_e],
        ['read_noise_dn', 'Read noise (DN rms)', fmt(doc.read_noise_dn, 4), doc.read_noise_dn],
        ['dark_dn', 'Dark signal (DN)', fmt(m.dark_dn, 6), m.dark_dn],
        ['saturation_dn', 'Saturation (DN above dark)', fmt(m.saturation_dn, 6), m.saturation_dn],
        ['linearity_range', 'Linearity range (DN above dark)',
            a != null ? `${fmt(sig(a), 5)} – ${fmt(sig(b), 5)}` : '–', null],
        ['linearity_error_pct', 'Linearity error (%)', fmt(m.linearity_error_pct, 3),
            m.linearity_error_pct],
    ];
    return h('table', { class: 'list', 'data-testid': 'ptc-table', dataset: { ptcId: m.id } },
        h('thead', {}, h('tr', {}, h('th', { scope: 'col' }, 'Figure'),
            h('th', { scope: 'col' }, `Measurement #${m.id}`))),
        h('tbody', {}, rows.map(([key, label, text, raw]) => h('tr', {},
            h('th', { scope: 'row' }, label),
            h('td', { dataset: { field: key, value: raw == null ? '' : String(raw) } }, text)))));
}

function history(items) {
    return h('table', { class: 'list', 'data-testid': 'ptc-history' },
        h('thead', {}, h('tr', {}, ['#', 'Measured', 'Gain (e⁻/DN)', 'Read noise (e⁻)', 'Job']
            .map((t) => h('th', { scope: 'col' }, t)))),
        h('tbody', {}, items.map((m, k) => h('tr', { dataset: { ptcId: m.id } },
            h('td', {}, `${m.id}${k === 0 ? ' (current)' : ''}`),
            h('td', {}, fmtTime(m.created_ms)),
            h('td', {}, fmt(m.gain_e_per_dn, 5)), h('td', {}, fmt(m.read_noise_e, 4)),
            h('td', {}, m.job_id ? `#${m.job_id}` : '–')))));
}

export function renderSensor(root, id, ctx) {
    const results = h('div', { class: 'ptc-results' });
    const status = h('p', { class: 'sub', 'data-testid': 'ptc-status', role: 'status' });
    const bar = h('progress', { max: 1, value: 0, hidden: true, 'aria-label': 'Measurement' });
    const btn = h('button', { type: 'button', 'data-testid': 'ptc-measure' },
        'Measure photon transfer');
    let jobId = null;
    const seen = new Map(); // the latest event of each job (one may come before the POST's answer)

    async function loadPtc() {
        let p;
        try {
            p = await get(`/api/sensors/${id}/ptc`);
        } catch (ex) {
            fill(results, failure(ex));
            return;
        }
        purgeIn(results);
        if (!p.current) {
            fill(results, h('p', { class: 'muted' },
                'Not measured yet: fits of this sensor use the constants it was created with.'));
            return;
        }
        fill(results, h('p', { class: 'sub' },
            `Measured ${fmtTime(p.current.created_ms)}: the sensor's fits use this gain and ` +
            'read noise for σ.'),
        figures(p.current), p.current.result ? ptcFigure(p.current.result) : null,
        h('h3', {}, 'History'), history(p.history));
    }

    function showJob(j) {
        const total = j.points_total || j.params?.levels || 0;
        bar.hidden = j.state !== 'running' && j.state !== 'queued';
        bar.value = j.progress ?? 0;
        fill(status, `Job #${j.id} `, stateBadge(j.state),
            j.state === 'running' && total ? ` level ${j.points_done ?? 0} of ${total}` : '',
            j.error ? ` — ${j.error}` : '');
        status.dataset.state = j.state;
    }

    btn.addEventListener('click', async () => {
        btn.disabled = true;
        try {
            const { job } = await post(`/api/sensors/${id}/ptc`, {});
            jobId = job.id;
            showJob(job);
            if (seen.has(job.id)) handle(seen.get(job.id));
            ctx.announce(`Photon-transfer measurement queued (job #${job.id})`);
        } catch (ex) {
            fill(status, h('span', { class: 'form-error', role: 'alert' }, ex.message));
            btn.disabled = false;
        }
    });

    function handle(ev) {
        showJob(ev);
        if (['done', 'failed', 'cancelled'].includes(ev.state)) {
            btn.disabled = false;
            if (ev.state === 'done') loadPtc();
        }
    }
    const stop = ctx.onJob((ev) => {
        if (ev.kind !== 'ptc') return;
        seen.set(ev.id, ev);
        if (ev.id === jobId) handle(ev);
    });

    (async () => {
        let s;
        try {
            s = await get(`/api/sensors/${id}`);
        } catch (ex) {
            fill(root, failure(ex));
            return;
        }
        fill(root, h('p', { class: 'crumbs' }, h('a', { href: `#/calibrations?sensor=${id}` },
            'Calibrations of this sensor')),
        h('h2', {}, `Sensor ${s.model} ${s.serial}`),
        h('section', { class: 'panel', 'aria-label': 'Constants' },
            h('dl', { class: 'facts' },
                ['Array', `${s.n_cols} × ${s.n_rows} pixels`, 'Pitch', `${fmt(s.pitch_um, 6)} µm`,
                    'Gain (as created)', `${fmt(s.gain_e_per_dn)} e⁻/DN`,
                    'Read noise (as created)', `${fmt(s.read_noise_e)} e⁻`,
                    'Bias', `${fmt(s.bias_dn, 6)} DN`,
                    'Full scale', `${fmt(s.full_scale_dn, 6)} DN`]
                    .map((t, k) => h(k % 2 ? 'dd' : 'dt', {}, t)))),
        h('section', { class: 'panel', 'aria-label': 'Photon transfer' },
            h('h3', {}, 'Photon transfer (EMVA 1288)'),
            h('p', { class: 'muted small' }, 'Pairs of flat frames and darks at a series of ' +
                'exposures on the bench give the conversion gain, read noise, dark signal, ' +
                'saturation and linearity range.'),
            h('div', { class: 'row-many' }, btn, bar), status, results));
        loadPtc();
    })();
    return () => {
        stop();
        purgeIn(results);
    };
}
