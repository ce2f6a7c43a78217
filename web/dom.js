// dom.js: small DOM functions shared by the views: element building (text only, never HTML from
// data), number / time formatting, reading a form into a nested JSON body, and showing an API
// error (message and offending field) next to the form that caused it.

// h('div', {class: 'x', onclick: fn, dataset: {id: 1}}, child, 'text', [more]) -> element
export function h(tag, attrs, ...children) {
    const el = tag.startsWith('svg:')
        ? document.createElementNS('http://www.w3.org/2000/svg', tag.slice(4))
        : document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
        if (v === undefined || v === null || v === false) continue;
        if (k === 'dataset') Object.assign(el.dataset, v);
        else if (k.startsWith('on') && typeof v === 'function') el.addEventListener(k.slice(2), v);
        else if (k === 'text') el.textContent = v;
        else el.setAttribute(k, v === true ? '' : String(v));
    }
    append(el, children);
    return el;
}

// Replaces el's children (arrays flattened; null, undefined and false left out).
export function fill(el, ...children) {
    el.replaceChildren();
    append(el, children);
    return el;
}

function append(el, children) {
    for (const c of children) {
        if (c === null || c === undefined || c === false) continue;
        if (Array.isArray(c)) append(el, c);
        else el.append(c instanceof Node ? c : document.createTextNode(String(c)));
    }
}

// A number with n significant digits ('–' for null / NaN); exponent form for tiny and huge.
export function fmt(v, n = 4) {
    if (v === null || v === undefined || !Number.isFinite(Number(v))) return '–';
    const x = Number(v);
    if (x !== 0 && (Math.abs(x) < 1e-3 || Math.abs(x) >= 1e6)) return x.toExponential(n - 1);
    return Number(x.toPrecision(n)).toString();
}

export function fmtTime(ms) {
    if (!ms) return '–';
    const d = new Date(ms);
    const pad = (x) => String(x).padStart(2, '0');
    return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())} ` +
        `${pad(d.getHours())}:${pad(d.getMinutes())}:${pad(d.getSeconds())}`;
}

export function fmtDuration(s) {
    if (s === null || s === undefined || !Number.isFinite(s)) return '';
    if (s < 60) return `${Math.max(0, Math.round(s))} s`;
    if (s < 3600) return `${Math.floor(s / 60)} min ${Math.round(s % 60)} s`;
    return `${Math.floor(s / 3600)} h ${Math.round((s % 3600) / 60)} min`;
}

// Reads the enabled inputs with data-field="a.b" into {a: {b: value}}; data-type int|num|str|
// bool. Empty inputs are left out (the server's defaults apply; required ones are reported by
// the server). A number that does not parse is sent as the text, so the server names it.
export function formBody(form) {
    const body = {};
    for (const el of form.querySelectorAll('[data-field]')) {
        if (el.disabled) continue;
        const type = el.dataset.type || 'str';
        let v;
        if (type === 'bool') v = el.checked;
        else {
            const raw = el.value.trim();
            if (raw === '') continue;
            if (type === 'int' || type === 'num') {
                const x = Number(raw);
                v = Number.isFinite(x) ? x : raw;
            } else v = raw;
        }
        const path = el.dataset.field.split('.');
        let o = body;
        for (const k of path.slice(0, -1)) o = o[k] ??= {};
        o[path[path.length - 1]] = v;
    }
    return body;
}

// The API's message in words: the field's JSON name (raster.step_um) replaced by the label of
// its input (Step (µm)), or the label put first when the message does not name it.
export function inWords(message, field, label) {
    if (!field || !label) return message;
    return message.includes(field) ? message.split(field).join(label) : `${label}: ${message}`;
}

// Shows err (an ApiError or Error) at the form: when it names a field of the form, in words
// right under that field's input (which is marked invalid and focused), and in the form's
// error box (role=alert) either way; the box keeps the field's JSON name in data-error-field.
export function showError(form, err) {
    clearError(form);
    const box = form.querySelector('.form-error');
    const field = err.field || null;
    const input = field && form.querySelector(`[data-field="${CSS.escape(field)}"]`);
    const label = input?.closest('label')?.querySelector('.lbl')?.textContent.trim() || null;
    const text = inWords(err.message, input ? field : null, label);
    fill(box, h('strong', {}, 'Error: '), text,
        field && !input ? h('span', { class: 'field' }, ` (field: ${field})`) : null);
    box.dataset.errorField = field || '';
    box.dataset.errorCode = err.code || '';
    box.hidden = false;
    if (input) {
        const at = h('small', { class: 'field-error', id: `${box.id}-at`,
            'data-testid': 'field-error' }, text);
        input.insertAdjacentElement('afterend', at);
        input.setAttribute('aria-invalid', 'true');
        input.setAttribute('aria-describedby', at.id);
        input.focus();
    }
}

export function clearError(form) {
    const box = form.querySelector('.form-error');
    if (box) {
        box.hidden = true;
        fill(box);
    }
    for (const el of form.querySelectorAll('.field-error')) el.remove();
    for (const el of form.querySelectorAll('[aria-invalid]')) {
        el.removeAttribute('aria-invalid');
        el.removeAttribute('aria-describedby');
    }
}

// Submits form through send(body) (the API call and what follows it): the error box is cleared
// first, the submit button disabled while it runs, and an API error shown at the form.
export function onSubmit(form, send) {
    form.addEventListener('submit', async (e) => {
        e.preventDefault();
        clearError(form);
        const btn = form.querySelector('button[type=submit]');
        btn.disabled = true;
        try {
            await send(formBody(form));
        } catch (ex) {
            showError(form, ex);
        } finally {
            btn.disabled = false;
        }
    });
}

let errorSeq = 0;
// The error box a form shows API errors in (role=alert, so screen readers announce it).
export function errorBox() {
    return h('p', { class: 'form-error', role: 'alert', id: `form-error-${++errorSeq}`,
        hidden: true });
}

// A labelled input: field(label, {data-field, ...input attributes}, hint?)
export function field(label, attrs, hint) {
    const id = attrs.id || `f-${(attrs['data-field'] || label).replace(/[^a-z0-9]+/gi, '-')}-` +
        `${++errorSeq}`;
    return h('label', { class: 'fld', for: id }, h('span', { class: 'lbl' }, label),
        h('input', { id, ...attrs }), hint ? h('small', {}, hint) : null);
}

// A message for a view that failed to load.
export function failure(err) {
    return h('p', { class: 'load-error', role: 'alert' }, `Cannot load: ${err.message}`,
        err.field ? ` (field: ${err.field})` : '');
}

export function stateBadge(state) {
    return h('span', { class: `state state-${state}`, dataset: { state } }, state);
}
