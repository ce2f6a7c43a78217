// rules.js: the server's rules for the forms' inputs, read from the served OpenAPI document
// (GET /api/openapi.json, fetched once per page). Each request body schema's properties carry
// the default and the bounds the server validates with (default, minimum, maximum,
// exclusiveMinimum, maxLength, enum), so the dashboard repeats none of them: the forms take
// their values, placeholders and min / max attributes from here.
import { get } from './api.js';
import { h } from './dom.js';

let doc = null; // the promise of the document

function openapi() {
    doc ??= get('/api/openapi.json').catch((err) => {
        doc = null; // a failed read is tried again by the next view
        throw err;
    });
    return doc;
}

// A schema with its local $ref followed and the properties of its allOf parts merged.
function resolve(d, s) {
    if (!s) return {};
    if (s.$ref) return resolve(d, d.components?.schemas?.[s.$ref.split('/').pop()]);
    if (!s.allOf) return s;
    const parts = s.allOf.map((p) => resolve(d, p));
    return { ...s, properties: Object.assign({}, ...parts.map((p) => p.properties), s.properties) };
}

// The rules of the JSON body of METHOD PATH as the document names them (e.g. 'post',
// '/api/scans/{id}/fits'): resolves to a function from a dotted field ('raster.area_px') to that
// field's schema ({} when the document has none).
export async function requestRules(method, path) {
    const d = await openapi();
    const op = d.paths?.[path]?.[method];
    const body = resolve(d, op?.requestBody?.content?.['application/json']?.schema);
    return (field) => field.split('.').reduce((s, k) => resolve(d, s.properties?.[k]), body);
}

// The range of a field in words, e.g. '1 to 101, default 5', '> 0, ≤ 1.7, default 0.25'.
export function rangeText(rule) {
    const has = (k) => rule[k] !== undefined && rule[k] !== null;
    const parts = [];
    if (has('minimum') && has('maximum')) {
        parts.push(`${rule.minimum} to ${rule.maximum}`);
    } else {
        if (has('minimum')) parts.push(`≥ ${rule.minimum}`);
        else if (has('exclusiveMinimum')) parts.push(`> ${rule.exclusiveMinimum}`);
        if (has('maximum')) parts.push(`≤ ${rule.maximum}`);
        else if (has('exclusiveMaximum')) parts.push(`< ${rule.exclusiveMaximum}`);
    }
    if (has('default')) parts.push(`default ${rule.default}`);
    return [parts.join(', '), rule.description].filter(Boolean).join('. ');
}

// Input attributes from a field's rule: the default as the value (or as the placeholder, for
// fields best left to the server: empty inputs are not sent), minimum / maximum as min / max,
// exclusiveMinimum / exclusiveMaximum as data-exclusive-min / -max (HTML has no open bounds),
// maxLength as maxlength, and a title that says the range.
export function ruleAttrs(rule, { placeholder = false } = {}) {
    const a = {};
    const def = rule.default;
    if (def !== undefined && def !== null && typeof def !== 'object') {
        a[placeholder ? 'placeholder' : 'value'] = def;
    }
    if (rule.minimum !== undefined) a.min = rule.minimum;
    if (rule.maximum !== undefined) a.max = rule.maximum;
    if (rule.exclusiveMinimum !== undefined) a['data-exclusive-min'] = rule.exclusiveMinimum;
    if (rule.exclusiveMaximum !== undefined) a['data-exclusive-max'] = rule.exclusiveMaximum;
    if (rule.maxLength !== undefined) a.maxlength = rule.maxLength;
    const title = rangeText(rule);
    if (title) a.title = title;
    return a;
}

// The <option>s of a field with an enum, its default selected.
export function choices(rule) {
    return (rule.enum || []).map((v) => h('option', { value: v, selected: v === rule.default },
        String(v)));
}
