// fit.js: the Fit view: one fit (GET /api/fits/{id}, the `ips fit` document). First the map the
// fit stores as its pixel's calibration (recommended, shrunk or kriged: fit_stored.js): one
// sentence on how it was made, its grid S and S_err, and whether it is the pixel's current
// calibration, with the action that makes it so (POST /api/fits/{id}/promote, with a reason).
// Then the fit's result and the F-test verdict (paper: reject H0 when p < 0.05), and the
// Comparison: any map of the fit (the sweep's r x r maps, the shrunk map, the kriged map) beside
// the Wiener-deconvolution baseline on one colour scale, its uncertainties S_err, the interpolated
// map as a 3-D surface, and the measured signal, the fitted model and the normalised residuals at
// the spot positions (Plotly figures on um axes, fit_maps.js), the goodness of fit in words; the
// model-selection figure (AIC, BIC, chi2 and the cross-validation chi2 against r, the recommended
// r marked and its reason in words, fit_select.js) with its table; and a re-fit with other
// settings (fit_form.js).
import { get, post } from './api.js';
import { errorBox, failure, field, fill, fmt, fmtTime, h, onSubmit } from './dom.js';
import { purgeIn } from './charts.js';
import { buildFitForm } from './fit_form.js';
import {
    errFigure, fitPoints, mapPairFigure, resFigure, residualFigure, surfaceFigure,
} from './fit_maps.js';
import { goodness, reasonText, selectionFigure } from './fit_select.js';
import { geometryFacts } from './fit_geometry.js';
import { storedContent, storedKind } from './fit_stored.js';
import { requestRules, ruleAttrs } from './rules.js';

const ALPHA = 0.05; // the paper's significance level for the F-test

// The model-selection figure, the recommended r's reason in words, and the table; note: the
// line under them that says which map the maps above show (updated when another r is chosen).
function selection(res, rec, note) {
    const fits = res.fits, best = res.best_r || {};
    const table = h('table', { class: 'list num', 'data-testid': 'sweep-table' },
        h('thead', {}, h('tr', {}, ['r', 'params', 'χ²', 'χ²/dof', 'p', 'CV χ²', 'AIC', 'BIC',
            'cond', 'status'].map((t) => h('th', { scope: 'col' }, t)))),
        h('tbody', {}, fits.map((f) => h('tr', { class: [f.r === best.aic ? 'best-aic' : '',
            f.r === best.bic ? 'best-bic' : ''].join(' ').trim() || null },
        h('td', {}, f.r, f.r === rec ? h('span', { class: 'tag rec' }, 'rec.') : null,
            f.r === best.aic ? h('span', { class: 'tag aic' }, 'AIC') : null,
            f.r === best.bic ? h('span', { class: 'tag bic' }, 'BIC') : null),
        h('td', {}, f.params), h('td', {}, fmt(f.chi2, 6)), h('td', {}, fmt(f.chi2_red)),
        h('td', {}, fmt(f.chi2_p, 2)), h('td', {}, fmt(f.cv_chi2, 6)),
        h('td', {}, fmt(f.aic, 6)), h('td', {}, fmt(f.bic, 6)), h('td', {}, fmt(f.cond, 3)),
        h('td', {}, f.status)))));
    return [selectionFigure(res, rec),
        h('p', { 'data-testid': 'selection-reason' }, reasonText(res, rec)), note,
        h('div', { class: 'table-wrap' }, table)];
}

// Re-fit of the fit's pixel with other settings (fit_form.js, POST /api/scans/{id}/fits), the
// choice whether the new fit becomes the calibration included; once queued, a line follows the
// job and links the new fit when it is done.
function refitPanel(fit, scan, ctx) {
    const box = h('div', { 'data-testid': 'refit' });
    const state = h('p', { class: 'muted small', 'data-testid': 'refit-state', role: 'status' });
    let stop = () => {};
    requestRules('post', '/api/scans/{id}/fits').then((rule) => {
        const form = buildFitForm(rule, scan, (reply) => {
            const job = reply.job;
            ctx?.announce?.(`Fit job #${job.id} queued`);
            fill(state, `Fit job #${job.id} queued…`);
            stop();
            const check = async () => {
                const j = await get(`/api/jobs/${job.id}`);
                if (j.state === 'done' && j.fit_id) {
                    stop();
                    fill(state, `Fit job #${job.id} done: `, h('a', { href: `#/fits/${j.fit_id}`,
                        'data-testid': 'refit-link' }, `fit #${j.fit_id}`),
                    body.promote ? ' (asked to become the calibration)' : '');
                } else if (j.state === 'failed' || j.state === 'cancelled') {
                    stop();
                    fill(state, `Fit job #${job.id} ${j.state}${j.error ? `: ${j.error}` : ''}`);
                }
            };
            const body = { promote: form.querySelector('[data-field="promote"]').checked };
            stop = ctx?.onJob ? ctx.onJob((ev) => {
                if (ev.id === job.id) check().catch(() => {});
            }) : () => {};
            check().catch(() => {});
        }, { title: 'Fit this pixel again with other settings', dcol: fit.dcol, drow: fit.drow,
            single: true });
        fill(box, form, state);
    }).catch((err) => fill(box, failure(err)));
    box.cleanup = () => stop();
    return box;
}

function ftestPanel(t) {
    if (!t) return h('p', { class: 'muted', 'data-testid': 'ftest-verdict' },
        'No F-test was requested for this fit.');
    if (t.error) return h('p', { class: 'err', 'data-testid': 'ftest-verdict' },
        `F-test failed: ${t.error}`);
    const sig = Number.isFinite(t.p_value) && t.p_value < ALPHA;
    const edges = (t.edges || []).join(', ');
    return h('div', {},
        h('p', { class: `verdict ${sig ? 'sig' : 'nosig'}`, 'data-testid': 'ftest-verdict',
            dataset: { significant: String(sig) } },
        sig ? `Significant (p < ${ALPHA}): H₀ rejected, the sensitivity inside the pixel ` +
            'is not constant.' : `Not significant (p ≥ ${ALPHA}): H₀ kept, the interior is ` +
            'consistent with a constant sensitivity.'),
        h('dl', { class: 'facts' },
            h('dt', {}, 'F'), h('dd', { 'data-testid': 'ftest-F', dataset: { value: t.F } },
                fmt(t.F, 6)),
            h('dt', {}, 'p'), h('dd', { 'data-testid': 'ftest-p', dataset: { value: t.p_value } },
                fmt(t.p_value, 4)),
            h('dt', {}, 'H₀'), h('dd', {}, `edge sub-pixels (${edges}) free, the rest one ` +
                `constant: ${t.params_H0} parameters, χ² = ${fmt(t.chi2_H0, 6)}`),
            h('dt', {}, 'H₁'), h('dd', {}, `full ${t.r}×${t.r} map: ${t.params_H1} ` +
                `parameters, χ² = ${fmt(t.chi2_H1, 6)}`),
            h('dt', {}, 'Data points'), h('dd', {}, t.N),
            h('dt', {}, 'Status'), h('dd', {}, t.status)));
}

// The fit's place in the lab database (fit.calibration, docs/api.md): whether its map (kind:
// recommended, shrunk or kriged, fit_stored.js) is the pixel's current calibration and, when it
// is not, a form with a reason that makes it so. After a promotion the panel is read again and
// the focus goes to its new state.
function calibrationPanel(fit, kind) {
    const box = h('div', { 'data-testid': 'fit-calibration' });
    const show = async (f, focus) => {
        const c = f.calibration;
        const state = (cls, current, ...text) => h('p', { class: cls, tabindex: -1,
            'data-testid': 'calibration-state', dataset: { current } }, ...text);
        if (!c) {
            fill(box, state('muted', 'none', 'This fit offers no map to store as a calibration ' +
                '(no admissible map, or an uploaded scan file without a sensor pixel).'));
            return;
        }
        const pixel = h('a', { href: `#/sensors/${c.sensor_id}/pixels/${c.pixel.col}/` +
            `${c.pixel.row}` }, `pixel (${c.pixel.col}, ${c.pixel.row})`);
        const st = c.current
            ? state('ok', 'true', `Its ${kind ? `${kind} ` : ''}${c.r} × ${c.r} map is the ` +
                'current calibration of ', pixel,
                ` (calibration #${c.current_calibration_id}).`)
            : state(null, 'false', `Stored as a fit: its ${kind ? `${kind} ` : ''}${c.r} × ` +
                `${c.r} map is not the calibration of `, pixel,
                c.current_calibration_id ? ` (the current one is calibration ` +
                    `#${c.current_calibration_id}).` : ' (which has none).');
        let form = null;
        if (!c.current) {
            const rule = await requestRules('post', '/api/fits/{id}/promote')
                .catch(() => () => ({}));
            form = h('form', { class: 'inline-form', novalidate: true,
                'aria-label': 'Make this fit the calibration', 'data-testid': 'promote-form' },
            h('div', { class: 'row-many' },
                field('Reason', { 'data-field': 'reason', ...ruleAttrs(rule('reason')),
                    placeholder: `fit ${f.id} promoted` }),
                h('input', { type: 'hidden', 'data-field': 'by', value: 'dashboard' })),
            errorBox(), h('button', { type: 'submit' }, 'Make this the calibration'));
            onSubmit(form, async (body) => {
                await post(`/api/fits/${f.id}/promote`, body);
                await show(await get(`/api/fits/${f.id}`), true);
            });
        }
        fill(box, st, form);
        if (focus) st.focus();
    };
    show(fit, false).catch((err) => fill(box, failure(err)));
    return box;
}

export function renderFit(root, id, ctx) {
    let refit = null;
    fill(root, h('p', { class: 'muted' }, `Loading fit #${id}…`));
    (async () => {
        const fit = await get(`/api/fits/${id}`);
        const res = fit.result || {};
        const scan = fit.scan_id ? await get(`/api/scans/${fit.scan_id}`).catch(() => null) : null;
        // the pitch for the maps' um axes: the scan's sensor, or the sensor an uploaded scan file
        // was fitted for (fit.calibration names it)
        const sensorId = scan?.sensor_id ?? fit.calibration?.sensor_id;
        const sensor = sensorId ? await get(`/api/sensors/${sensorId}`).catch(() => null) : null;
        const pitch = sensor?.pitch_um;
        // which map the fit stores as its pixel's calibration (fit_stored.js)
        const stored = await storedKind(fit);
        const best = res.best_r || {};
        const fits = res.fits || [];
        // the recommended r (fits stored before the recommendation existed: the best BIC), the
        // map the Comparison shows first
        const rec = res.recommended_r !== undefined ? res.recommended_r : best.bic;
        // the shrunk map (fit/shrink.h): the recommended map's detail over r - 1 kept where it
        // stands above its noise, offered as one more choice of the selector
        const sh = res.shrunk_map;
        // the kriged map (fit/krige.h, a fit request's "krige": true): a Gaussian-process
        // estimate on a fine grid, one more choice when the fit has it
        const kr = res.kriged_map && Array.isArray(res.kriged_map.S) ? res.kriged_map : null;
        const rSel = h('select', { id: 'r-select', 'data-testid': 'r-select' },
            fits.map((f) => h('option', { value: f.r, selected: f.r === rec },
                `r = ${f.r}${f.r === rec ? ' (recommended)' : ''}` +
                `${f.r === best.bic ? ' (best BIC)' : ''}${f.r === best.aic ? ' (best AIC)' : ''}`)),
            sh ? h('option', { value: 'shrunk' }, `r = ${sh.r}, shrunk toward r = ${sh.toward_r}`)
                : null,
            kr ? h('option', { value: 'kriged' }, `kriged, ${kr.grid} × ${kr.grid}`) : null);
        const facts = h('dl', { class: 'facts' }); // of the map the Comparison shows
        const note = h('p', { class: 'muted small', 'data-testid': 'selection-note' });
        const maps = h('div', { class: 'maps' });
        // the map stored, in the note's words
        const storedWords = stored.kind === 'kriged' ? 'the kriged map'
            : stored.kind === 'shrunk' ? 'the shrunk map'
                : stored.kind ? `the recommended r = ${rec ?? '–'}'s own map` : null;
        // the spot positions of the residuals, read once (fit_maps.js)
        const points = fitPoints(fit);
        points.catch(() => {});
        const show = () => {
            const shrunk = rSel.value === 'shrunk' && sh;
            const kriged = rSel.value === 'kriged' && kr;
            const fr = fits.find((x) => x.r === (shrunk ? sh.r : kriged ? rec
                : Number(rSel.value)));
            // the shrunk or kriged map shown in its fit's place (the fit's I0, status and
            // goodness are the recommended fit's; its residuals and interpolation are of the
            // fit's own map, so they are not shown with either)
            const f = shrunk && fr ? { ...fr, S: sh.S, S_err: sh.S_err }
                : kriged && fr ? { ...fr, r: kr.grid, S: kr.S, S_err: kr.S_err } : fr;
            const own = !shrunk && !kriged;
            if (!f) {
                fill(maps, h('p', { class: 'muted' }, 'This fit has no maps.'));
                return;
            }
            fill(facts,
                h('dt', {}, 'Map shown'), h('dd', { 'data-testid': 'shown-r' }, shrunk
                    ? `r = ${f.r}, shrunk toward r = ${sh.toward_r} ` +
                        `(${fmt(100 * sh.factor, 2)} % of the detail kept)`
                    : kriged ? `kriged, ${kr.grid} × ${kr.grid} (` + (kr.smooth
                        ? `smooth part: sd ${fmt(kr.amplitude, 2)}, length ` +
                            `${fmt(kr.length_um, 2)} µm, likelihood ratio ` +
                            `${fmt(kr.likelihood_ratio, 3)}`
                        : 'the recommended grid alone: no smooth part') + ')'
                        : `r = ${f.r}`),
                h('dt', {}, 'Fit status'), h('dd', { 'data-testid': 'map-status',
                    class: f.status === 'ok' ? 'ok' : 'warn' }, f.status),
                h('dt', {}, 'Goodness of fit'), (() => {
                    const g = goodness(f);
                    return h('dd', { class: `small ${g.cls}`, 'data-testid': 'goodness',
                        dataset: { poor: String(g.poor) } }, g.text);
                })(),
                h('dt', {}, 'I₀ (DN)'), h('dd', {}, `${fmt(f.I0, 6)} ± ${fmt(f.I0_err, 2)}`),
                h('dt', {}, 'Condition number'), h('dd', {}, fmt(f.cond, 3)));
            const storedNote = storedWords ? ` The map the fit stores as its pixel's ` +
                `calibration is ${storedWords} (first on this page).` : '';
            fill(note, `Best r by AIC: ${best.aic ?? '–'}, by BIC: ${best.bic ?? '–'}; ` +
                `recommended: ${rec ?? '–'}. The maps above ` + (kriged ? 'are the kriged ' +
                `map: a Gaussian-process estimate on a ${kr.grid} × ${kr.grid} grid with the ` +
                `recommended r = ${rec ?? '–'}'s grid in its prior (about half the best r's ` +
                'error in the fidelity harness).'
                : shrunk ? `are the shrunk ` +
                `map: r = ${f.r}'s detail over r = ${sh.toward_r} kept where it stands above ` +
                `its noise (closer to the truth than the recommended map in the fidelity ` +
                `harness).`
                : `are r = ${f.r}` + (f.r === rec ? ', the recommended r.' : `; the recommended ` +
                `r is ${rec ?? '–'}.`)) + storedNote);
            purgeIn(maps);
            if (!f.S) {
                fill(maps, h('p', { class: 'muted' }, `The r = ${f.r} fit has no map ` +
                    `(${f.status}).`));
                return;
            }
            const resid = h('div', { class: 'pfig-slot' }, h('p', { class: 'muted' },
                'Loading the spot positions…'));
            points.then((pts) => fill(resid, residualFigure(f, pts)), (err) => fill(resid,
                h('p', { class: 'muted', 'data-testid': 'resid-missing' },
                    `No residual plot: ${err.message}.`)));
            fill(maps, mapPairFigure(f, res.wiener, pitch),
                own ? surfaceFigure(`/api/fits/${fit.id}/interp?r=${f.r}`, pitch) : null,
                f.S_err ? errFigure(f, pitch) : null,
                !kriged && sh && sh.S_res && f.r === sh.r ? resFigure(sh.S_res, f.r, pitch)
                    : null,
                own ? resid : null);
        };
        rSel.addEventListener('change', show);
        const where = fit.scan_id
            ? [h('a', { href: `#/scans/${fit.scan_id}` }, `scan #${fit.scan_id}`),
                `, pixel offset (${fit.dcol}, ${fit.drow})`]
            : ['an uploaded scan file'];
        const calLink = scan ? h('a', { href: `#/sensors/${scan.sensor_id}/pixels/` +
            `${scan.poi.col + fit.dcol}/${scan.poi.row + fit.drow}` }, 'calibration history')
            : null;
        const axesNote = () => h('p', { class: 'muted small' }, 'Axes in µm (pixel widths when ' +
            'the sensor\'s pitch is unknown) from the pixel\'s top-left corner (y grows downward; ' +
            'the pixel outlined). Point at a map for its values, drag to zoom, double-click to ' +
            'reset; each figure\'s bar saves it as PNG (camera) or SVG (disk).');
        fill(root,
            h('p', { class: 'crumbs' }, h('a', { href: fit.scan_id ? `#/scans/${fit.scan_id}`
                : '#/scans' }, fit.scan_id ? `← Scan #${fit.scan_id}` : '← Scans')),
            h('h2', {}, `Fit #${fit.id}`),
            h('p', { class: 'sub' }, 'Of ', where, ` · ${fmtTime(fit.created_ms)} · `,
                h('a', { href: `/api/fits/${fit.id}`, download: `fit-${fit.id}.json` }, 'JSON'),
                calLink ? [' · ', calLink] : null),
            h('section', { class: 'panel', 'aria-labelledby': 'stored-h',
                'data-testid': 'stored-section', dataset: { map: stored.kind ?? 'none' } },
            h('h3', { id: 'stored-h' }, stored.kind ? `The calibration: the ${stored.kind} map`
                : 'The map'),
            storedContent(fit, stored, pitch), axesNote(),
            h('h4', { id: 'cal-h' }, 'Calibration'), calibrationPanel(fit, stored.kind)),
            h('div', { class: 'two-col fit-top' },
                h('section', { class: 'panel', 'aria-labelledby': 'sum-h' },
                    h('h3', { id: 'sum-h' }, 'Result'),
                    h('dl', { class: 'facts' },
                        h('dt', {}, 'Recommended r'),
                        h('dd', { 'data-testid': 'recommended-r',
                            title: res.recommended_reason || '' }, rec ?? '–'),
                        res.recommended_reason ? [h('dt', {}, 'Why'), h('dd', { class: 'small',
                            'data-testid': 'recommended-reason' }, res.recommended_reason)]
                            : null,
                        res.range_edge ? [h('dt', {}, 'Note'), h('dd', { class: 'warn',
                            'data-testid': 'range-edge' }, 'AIC or BIC picked the largest r the ' +
                            'sweep or the points allow: their choice sits at the edge of the ' +
                            'searched range')] : null,
                        h('dt', {}, 'Best r (AIC)'),
                        h('dd', { 'data-testid': 'best-r-aic' }, best.aic ?? '–'),
                        h('dt', {}, 'Best r (BIC)'),
                        h('dd', { 'data-testid': 'best-r-bic' }, best.bic ?? '–'),
                        h('dt', {}, 'Points used'),
                        h('dd', {}, `${res.N ?? '–'} of ${res.n_points ?? '–'}`),
                        h('dt', {}, 'Noise model'), h('dd', {}, `${res.sigma ?? fit.noise_model}, ` +
                            `${res.method ?? ''}${res.nonneg ? ', S ≥ 0' : ''}`),
                        geometryFacts(res.geometry))),
                h('section', { class: 'panel', 'aria-labelledby': 'ft-h' },
                    h('h3', { id: 'ft-h' }, 'F-test: is the centre of the pixel flat?'),
                    ftestPanel(res.ftest))),
            h('section', { class: 'panel', 'aria-labelledby': 'maps-h',
                'data-testid': 'comparison' },
            h('h3', { id: 'maps-h' }, 'Comparison'),
            h('p', { class: 'muted small' }, 'Every map of this fit: the sweep\'s r × r maps, ' +
                'the shrunk map and the kriged map where the fit has them, each beside the ' +
                'Wiener-deconvolution baseline.'),
            h('div', { class: 'two-col even' },
                h('div', {}, h('label', { class: 'fld inline', for: 'r-select' },
                    h('span', { class: 'lbl' }, 'Map '), rSel)), facts),
            axesNote(), maps),
            h('section', { class: 'panel', 'aria-labelledby': 'sel-h' },
                h('h3', { id: 'sel-h' }, 'Model selection'), fits.length ? selection(res, rec, note)
                    : h('p', { class: 'muted' }, 'No sweep in this fit.')),
            scan?.state === 'done' ? h('section', { class: 'panel', 'aria-labelledby': 'refit-h' },
                h('h3', { id: 'refit-h' }, 'Re-fit'), refit = refitPanel(fit, scan, ctx)) : null);
        show();
    })().catch((err) => fill(root, failure(err)));
    return () => refit?.cleanup();
}
