// app.js: the dashboard's entry point: the hash router (#/scans, #/scans/ID, #/fits/ID,
// #/calibrations?filters, #/sensors/ID/pixels/COL/ROW, #/sensors/ID: its photon transfer), the
// token field (kept in localStorage, sent as 'Authorization: Bearer'), the form asking for a
// token when reads answer 401 (token.js), the server's health and the event-stream status.
import { get, getToken, onEventStatus, onJob, setToken } from './api.js';
import { renderCalibrations, renderPixel } from './calib.js';
import { fill, h } from './dom.js';
import { setupTokenPrompt } from './token.js';
import { renderFit } from './fit.js';
import { renderScan } from './scan_detail.js';
import { renderScans } from './scans_list.js';
import { renderSensor } from './sensor.js';

const view = document.getElementById('view');
const notice = document.getElementById('notice');
let cleanup = () => {};
let noticeTimer = null;

// A short message in the header's live region (e.g. "Scan #3 queued").
function announce(text) {
    notice.textContent = text;
    clearTimeout(noticeTimer);
    noticeTimer = setTimeout(() => { notice.textContent = ''; }, 8000);
}

const ctx = { onJob, announce };

const routes = [
    [/^\/scans\/?$/, () => renderScans(view, ctx), 'scans'],
    [/^\/scans\/(\d+)$/, (m) => renderScan(view, Number(m[1]), ctx), 'scans'],
    [/^\/fits\/(\d+)$/, (m) => renderFit(view, Number(m[1]), ctx), 'scans'],
    [/^\/calibrations\/?$/, (m, q) => renderCalibrations(view, q), 'calibrations'],
    [/^\/sensors\/(\d+)$/, (m) => renderSensor(view, Number(m[1]), ctx), 'calibrations'],
    [/^\/sensors\/(\d+)\/pixels\/(\d+)\/(\d+)$/,
        (m) => renderPixel(view, Number(m[1]), Number(m[2]), Number(m[3])), 'calibrations'],
];

function route() {
    const hash = location.hash.replace(/^#/, '') || '/scans';
    const [path, query] = hash.split('?');
    cleanup();
    cleanup = () => {};
    for (const [re, fn, tab] of routes) {
        const m = path.match(re);
        if (!m) continue;
        for (const a of document.querySelectorAll('nav a')) {
            if (a.dataset.nav === tab) a.setAttribute('aria-current', 'page');
            else a.removeAttribute('aria-current');
        }
        cleanup = fn(m, new URLSearchParams(query || '')) || (() => {});
        return;
    }
    fill(view, h('h2', {}, 'Not found'),
        h('p', {}, `No page ${path}. `, h('a', { href: '#/scans' }, 'Go to the scans.')));
}

function setupToken() {
    const form = document.getElementById('token-form');
    const input = document.getElementById('token');
    const state = document.getElementById('token-state');
    input.value = getToken();
    const show = () => { state.textContent = getToken() ? 'token set' : 'no token'; };
    show();
    // reads closed: the prompt's token shows in the header too, and the view reads again
    setupTokenPrompt(view, () => {
        input.value = getToken();
        show();
        announce('Token set');
        route();
    });
    form.addEventListener('submit', (e) => {
        e.preventDefault();
        setToken(input.value.trim());
        show();
        announce(getToken() ? 'Token saved in this browser' : 'Token cleared');
    });
}

function setupStatus() {
    const live = document.getElementById('live');
    onEventStatus((s) => {
        live.textContent = `events: ${s.state}`;
        live.dataset.state = s.state;
        live.dataset.received = String(s.received);
        live.title = `${s.received} job events received` +
            (s.malformed ? `, ${s.malformed} damaged ones ignored` : '');
    });
    get('/api/health').then((hl) => {
        document.getElementById('health').textContent =
            `ipsd ${hl.version} · ${hl.bench} bench · ${hl.status}`;
    }).catch((err) => {
        document.getElementById('health').textContent = `server: ${err.message}`;
    });
}

setupToken();
setupStatus();
window.addEventListener('hashchange', route);
route();
