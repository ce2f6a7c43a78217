// fit_form.js: the Scan view's form to fit a pixel of a done scan's sub-frame with other options
// (POST /api/scans/ID/fits). The bounds and defaults of r and the noise models come from the
// server's rules (rules.js); the pixel offsets are bounded by the scan's own sub-frame. The fit
// becomes the pixel's calibration only when "becomes the calibration" is ticked (default off: a
// re-fit is stored as a fit, and can be promoted later from its Fit view). On the Scan view the
// form can also fit every pixel the raster covers ("pixels": "all", one job, docs/api.md): the
// pixel offsets are then disabled (not sent). "Map stored" is the map the fit offers as the
// calibration (recommended, shrunk or kriged; the server's rules list them).
import { post } from './api.js';
import { errorBox, field, h, onSubmit } from './dom.js';
import { choices, ruleAttrs } from './rules.js';

// rule: the rules of POST /api/scans/{id}/fits; scan: the scan (its id and sub-frame);
// onQueued(reply) after a 202; opts: the form's title and the pixel offsets to start from (the
// Fit view's re-fit starts from its own pixel).
export function buildFitForm(rule, scan, onQueued, opts = {}) {
    const err = errorBox();
    const int = (label, f, attrs = {}) => field(label, { 'data-field': f, 'data-type': 'int',
        type: 'number', step: 1, ...ruleAttrs(rule(f)), ...attrs });
    const h2 = Math.floor(scan.raster.sub_px / 2); // |dcol|, |drow| <= sub_px / 2
    const form = h('form', { class: 'inline-form', novalidate: true,
        'aria-label': 'Fit a pixel of this scan', 'data-testid': 'fit-form' },
    h('h4', {}, opts.title || 'Fit a pixel of the sub-frame'),
    opts.single ? null : pixelsChoice(rule),
    h('div', { class: 'row-many' },
        int('dcol', 'dcol', { min: -h2, max: h2, ...(opts.dcol !== undefined
            ? { value: opts.dcol } : {}) }),
        int('drow', 'drow', { min: -h2, max: h2, ...(opts.drow !== undefined
            ? { value: opts.drow } : {}) }),
        int('r min', 'r_min'), int('r max', 'r_max'),
        h('label', { class: 'fld' }, h('span', { class: 'lbl' }, 'σ model'),
            h('select', { 'data-field': 'sigma' }, choices(rule('sigma')))),
        // the paper's analysis (the automatic fit's, docs/api.md) rather than the API's
        // defaults (no F-test, no Wiener baseline): what one usually wants to compare with
        field('F-test edges', { 'data-field': 'ftest', value: 'top,left,bottom',
            title: rule('ftest').description }),
        int('F-test r', 'ftest_r'),
        h('label', { class: 'fld check' }, h('input', { type: 'checkbox', checked: true,
            'data-field': 'wiener', 'data-type': 'bool' }), ' Wiener baseline')),
    h('div', { class: 'row-many' },
        h('label', { class: 'fld', title: rule('map').description },
            h('span', { class: 'lbl' }, 'Map stored'),
            h('select', { 'data-field': 'map', 'data-testid': 'fit-map' }, choices(rule('map')))),
        h('label', { class: 'fld check', title: rule('promote').description },
            h('input', { type: 'checkbox', 'data-field': 'promote', 'data-type': 'bool',
                'data-testid': 'fit-promote' }), ' becomes the calibration'),
        field('Reason (kept with the calibration)', { 'data-field': 'reason',
            ...ruleAttrs(rule('reason')), placeholder: 'e.g. r ≤ 4 is what we use' }),
        h('input', { type: 'hidden', 'data-field': 'by', value: 'dashboard' })),
    err, h('button', { type: 'submit' }, 'Queue fit'));
    const which = form.querySelector('[data-field="pixels"]');
    which?.addEventListener('change', () => {
        for (const f of ['dcol', 'drow']) {
            form.querySelector(`[data-field="${f}"]`).disabled = which.value === 'all';
        }
    });
    onSubmit(form, async (body) => onQueued(await post(`/api/scans/${scan.id}/fits`, body)));
    return form;
}

// The choice between one pixel (dcol, drow) and every pixel the scan's raster covers.
function pixelsChoice(rule) {
    return h('div', { class: 'row-many' }, h('label', { class: 'fld', title:
        rule('pixels')?.description || '' }, h('span', { class: 'lbl' }, 'Pixels'),
    h('select', { 'data-field': 'pixels', 'data-testid': 'fit-pixels' },
        h('option', { value: '' }, 'the pixel dcol, drow'),
        h('option', { value: 'all' }, 'every pixel the raster covers'))));
}
