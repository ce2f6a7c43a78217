// scan_form.js: the form for a new scan (POST /api/scans): sensor, pixel of interest, optics
// (wavelength and NA, or a spot radius), raster, scene, set-up (the paper's procedure, or none:
// the POI's centre and the exposure as given, for a bench aligned by hand), exposure and seed. Every default
// and bound comes from the server's rules (rules.js, the served OpenAPI document), never from
// this file: the optics and raster are filled in with the server's defaults, the exposure and
// seed shown as placeholders (empty inputs are not sent, so the server's defaults apply). The
// pixel of interest is preset to the chosen sensor's centre.
import { post } from './api.js';
import { errorBox, field, fmt, h, onSubmit } from './dom.js';
import { choices, ruleAttrs } from './rules.js';

// rule: the rules of POST /api/scans (rules.js); sensorSelect: the sensor <select> (filled by
// the view); onQueued(reply) after a 202.
export function buildScanForm(rule, sensorSelect, onQueued) {
    const err = errorBox();
    // an input of field f with the server's rule; placeholder: its default as the placeholder
    const num = (label, f, { placeholder = false, ...attrs } = {}) => field(label, {
        'data-field': f, 'data-type': 'num', type: 'number', step: 'any',
        ...ruleAttrs(rule(f), { placeholder }), ...attrs });
    const int = (label, f, { placeholder = false, ...attrs } = {}) => field(label, {
        'data-field': f, 'data-type': 'int', type: 'number', step: 1,
        ...ruleAttrs(rule(f), { placeholder }), ...attrs });
    const wl = num('Wavelength (nm)', 'optics.wavelength_nm');
    const na = num('NA', 'optics.na');
    const radius = num('Spot radius (µm)', 'optics.spot_radius_um', { placeholder: true,
        disabled: true });
    const input = (f) => f.querySelector('input');
    // the radius the server derives from the wavelength and NA, R = 1.22 λ / (2 NA) (paper
    // eq. 1), shown as the radius input's placeholder
    const showRadius = () => {
        const lambdaUm = Number(input(wl).value) * 1e-3, aperture = Number(input(na).value);
        const r = 1.22 * lambdaUm / (2 * aperture);
        input(radius).placeholder = Number.isFinite(r) && r > 0 ? fmt(r) : '';
    };
    input(wl).addEventListener('input', showRadius);
    input(na).addEventListener('input', showRadius);
    showRadius();
    const mode = (m) => {
        input(na).disabled = m !== 'na';
        input(radius).disabled = m !== 'radius';
    };
    const radio = (value, label, checked) => h('label', { class: 'inline' },
        h('input', { type: 'radio', name: 'optics-mode', value, checked,
            onchange: () => mode(value) }), ` ${label}`);
    const form = h('form', { class: 'stack', novalidate: true, 'data-testid': 'scan-form',
        'aria-labelledby': 'new-scan-h' },
    h('label', { class: 'fld', for: 'scan-sensor' }, h('span', { class: 'lbl' }, 'Sensor'),
        sensorSelect),
    h('fieldset', {}, h('legend', {}, 'Pixel of interest'),
        h('div', { class: 'row2' }, int('Column', 'poi.col', { required: true }),
            int('Row', 'poi.row', { required: true }))),
    h('fieldset', {}, h('legend', {}, 'Optics'),
        h('div', { class: 'radios' }, radio('na', 'wavelength and NA', true),
            radio('radius', 'spot radius')),
        h('div', { class: 'row3' }, wl, na, radius)),
    h('fieldset', {}, h('legend', {}, 'Raster'),
        h('div', { class: 'row2' },
            int('Area (pixels, odd)', 'raster.area_px'), num('Step (µm)', 'raster.step_um')),
        h('div', { class: 'row2' },
            int('Sub-frame (pixels, odd)', 'raster.sub_px'),
            int('Frames per point', 'raster.frames'))),
    h('div', { class: 'row3' },
        h('label', { class: 'fld', for: 'scan-scene' }, h('span', { class: 'lbl' }, 'Scene'),
            h('select', { id: 'scan-scene', 'data-field': 'scene' }, choices(rule('scene')))),
        num('Exposure (µs)', 'exposure_us', { placeholder: true }),
        int('Seed', 'seed', { placeholder: true })),
    h('label', { class: 'fld', for: 'scan-setup', title: rule('setup').description || '' },
        h('span', { class: 'lbl' }, 'Set-up'),
        h('select', { id: 'scan-setup', 'data-field': 'setup' }, choices(rule('setup')))),
    h('p', { class: 'muted small', 'data-testid': 'setup-note' }, 'paper: exposure search, ' +
        'centring on the POI and focus before the raster; none: the POI\'s centre and the ' +
        'exposure as given (a bench aligned by hand, a camera checked with a test pattern).'),
    err,
    h('button', { type: 'submit', class: 'primary' }, 'Start scan'));
    // the pixel of interest starts at the chosen sensor's centre pixel; a value typed in stays
    // (only an empty field, or the centre this form put there, follows the sensor)
    const presetPoi = () => {
        const o = sensorSelect.selectedOptions[0];
        if (!o || !o.dataset.cols) return;
        const centre = { 'poi.col': Math.floor(o.dataset.cols / 2),
            'poi.row': Math.floor(o.dataset.rows / 2) };
        for (const [f, v] of Object.entries(centre)) {
            const el = form.querySelector(`input[data-field="${f}"]`);
            if (el.value === '' || el.value === el.dataset.preset) {
                el.value = String(v);
                el.dataset.preset = String(v);
            }
        }
    };
    sensorSelect.addEventListener('change', presetPoi);
    presetPoi();
    onSubmit(form, async (body) => onQueued(await post('/api/scans', body)));
    return form;
}
