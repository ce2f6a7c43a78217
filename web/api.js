// api.js: talking to ipsd: JSON requests with the bearer token (for servers run with --token or
// --read-token), errors as ApiError {status, code, message, field} taken from the API's error
// body, a signal when a request answers 401 (token.js asks for a token then), and one shared
// EventSource on /api/events that hands job events to whoever subscribed. An EventSource cannot
// send a header, so the stream is opened with a short-lived ticket of POST /api/events/ticket
// (docs/api.md, Conventions), and opened again with a new ticket when the browser gives it up.

const TOKEN_KEY = 'ipsd.token';
const RETRY_MS = 3000; // a closed stream is opened again after this (the server's retry: too)

export class ApiError extends Error {
    constructor(status, code, message, field) {
        super(message);
        this.name = 'ApiError';
        this.status = status;
        this.code = code;
        this.field = field || null;
    }
}

let pageToken = ''; // when the browser's storage is disabled: the token lasts for this page

// The token: this tab's (sessionStorage) first, then the one remembered in this browser.
export function getToken() {
    try {
        return sessionStorage.getItem(TOKEN_KEY) || localStorage.getItem(TOKEN_KEY) || pageToken;
    } catch {
        return pageToken;
    }
}

// Keeps the token in this browser (remember: localStorage, across tabs and restarts) or for this
// tab only (sessionStorage); '' forgets it in both. The event stream reconnects with it.
export function setToken(token, remember = true) {
    pageToken = token;
    try {
        sessionStorage.removeItem(TOKEN_KEY);
        localStorage.removeItem(TOKEN_KEY);
        if (token) (remember ? localStorage : sessionStorage).setItem(TOKEN_KEY, token);
    } catch {
        /* storage disabled: pageToken */
    }
    if (generation) reconnect(0);
}

// ---- a token needed: the reads answered 401 ----

const authListeners = new Set();

// Calls fn(error) when a request answers 401 (the server wants a token, or another one);
// returns the function that stops it.
export function onAuthNeeded(fn) {
    authListeners.add(fn);
    return () => authListeners.delete(fn);
}

// One request. Resolves with the parsed JSON body (or text for non-JSON replies); rejects with
// ApiError, also for network failures (status 0).
export async function request(method, path, body) {
    const headers = { Accept: 'application/json' };
    const init = { method, headers };
    if (body !== undefined) {
        headers['Content-Type'] = 'application/json';
        init.body = JSON.stringify(body);
    }
    const token = getToken();
    if (token) headers.Authorization = `Bearer ${token}`;
    let res;
    try {
        res = await fetch(path, init);
    } catch (e) {
        throw new ApiError(0, 'network', `cannot reach ipsd: ${e.message}`, null);
    }
    const text = await res.text();
    let data = text;
    if ((res.headers.get('Content-Type') || '').startsWith('application/json') && text) {
        try {
            data = JSON.parse(text);
        } catch {
            data = text;
        }
    }
    if (!res.ok) {
        const e = data && typeof data === 'object' ? data.error : null;
        const err = new ApiError(res.status, e?.code || `http_${res.status}`,
            e?.message || `${res.status} ${res.statusText}`, e?.field);
        // a read refused: the page needs a token (a refused write says so at its form)
        if (res.status === 401 && (method === 'GET' || path === '/api/events/ticket')) {
            authListeners.forEach((fn) => fn(err));
        }
        throw err;
    }
    return data;
}

export const get = (path) => request('GET', path);
export const post = (path, body) => request('POST', path, body ?? {});

// ---- server-sent events ----

const listeners = new Set();
const statusListeners = new Set();
let source = null;
let stats = { state: 'connecting', received: 0, malformed: 0 };

function setStatus(state) {
    stats = { ...stats, state };
    statusListeners.forEach((fn) => fn(stats));
}

let retryTimer = null;
let generation = 0; // a newer connect() makes an older one's late answers moot

// The stream's URL: with a ticket when the server gives one (its reads may be closed); without,
// from a server that has no ticket endpoint. Throws the ApiError of a 401 (no or wrong token).
async function streamUrl() {
    try {
        const t = await request('POST', '/api/events/ticket', {});
        return `/api/events?ticket=${encodeURIComponent(t.ticket)}`;
    } catch (e) {
        if (e.status === 401 || e.status === 0) throw e;
        return '/api/events'; // e.g. 404 from an older ipsd
    }
}

function reconnect(ms) {
    clearTimeout(retryTimer);
    retryTimer = setTimeout(() => {
        retryTimer = null;
        connect();
    }, ms);
}

async function connect() {
    const mine = ++generation;
    if (source) source.close();
    source = null;
    let url;
    try {
        url = await streamUrl();
    } catch (e) {
        if (mine !== generation) return;
        setStatus(e.status === 401 ? 'locked' : 'closed'); // locked: setToken reconnects
        if (e.status !== 401) reconnect(RETRY_MS);
        return;
    }
    if (mine !== generation) return;
    const es = new EventSource(url);
    source = es;
    es.onopen = () => setStatus('live');
    es.onerror = () => {
        if (es.readyState !== EventSource.CLOSED) {
            setStatus('reconnecting'); // the browser tries again with the same URL
            return;
        }
        // given up (e.g. a 401 once the ticket expired, or ipsd restarted): a new ticket
        setStatus('closed');
        if (source === es) reconnect(RETRY_MS);
    };
    es.addEventListener('job', (ev) => {
        let job;
        try {
            job = JSON.parse(ev.data);
        } catch {
            stats.malformed++; // a damaged event: the views also re-read state on their own
            setStatus(stats.state);
            return;
        }
        stats.received++;
        setStatus('live');
        listeners.forEach((fn) => fn(job));
    });
}

// Calls fn(job) for every job event; returns the function that stops it.
export function onJob(fn) {
    if (!generation) connect();
    listeners.add(fn);
    return () => listeners.delete(fn);
}

// Calls fn({state, received, malformed}) when the stream's state changes.
export function onEventStatus(fn) {
    if (!generation) connect();
    statusListeners.add(fn);
    fn(stats);
    return () => statusListeners.delete(fn);
}
