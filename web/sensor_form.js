// sensor_form.js: the "New sensor…" form of the Scans view (POST /api/sensors). The defaults
// (the paper's sensor) and the bounds come from the server's rules (rules.js): the size and pitch
// are filled in, the other constants shown as placeholders and left to the server when empty.
import { post } from './api.js';
import { errorBox, field, h, onSubmit } from './dom.js';
import { ruleAttrs } from './rules.js';

// rule: the rules of POST /api/sensors (rules.js); onCreated(sensor) after a 201.
export function buildSensorForm(rule, onCreated) {
    const err = errorBox();
    const num = (label, f, placeholder) => field(label, { 'data-field': f, 'data-type': 'num',
        type: 'number', step: 'any', ...ruleAttrs(rule(f), { placeholder }) });
    const int = (label, f) => field(label, { 'data-field': f, 'data-type': 'int', type: 'number',
        step: 1, ...ruleAttrs(rule(f)) });
    const text = (label, f, example) => field(label, { 'data-field': f, placeholder: example,
        required: true, ...ruleAttrs(rule(f)) });
    const form = h('form', { class: 'stack', novalidate: true, 'aria-label': 'New sensor',
        'data-testid': 'sensor-form' },
    h('div', { class: 'row2' }, text('Model', 'model', 'e.g. IMX290'),
        text('Serial', 'serial', 'e.g. SN-0001')),
    h('div', { class: 'row3' }, int('Columns', 'n_cols'), int('Rows', 'n_rows'),
        num('Pitch (µm)', 'pitch_um', false)),
    h('div', { class: 'row2' }, num('Gain (e⁻/DN)', 'gain_e_per_dn', true),
        num('Read noise (e⁻)', 'read_noise_e', true)),
    h('div', { class: 'row2' }, num('Bias (DN)', 'bias_dn', true),
        num('Full scale (DN)', 'full_scale_dn', true)),
    err,
    h('button', { type: 'submit' }, 'Create sensor'));
    const details = h('details', { class: 'new-sensor' }, h('summary', {}, 'New sensor…'), form);
    onSubmit(form, async (body) => {
        const s = await post('/api/sensors', body);
        details.open = false;
        form.reset();
        await onCreated(s);
    });
    return details;
}
