// api.js: talking to ipsd: JSON requests with the bearer token (for servers run with --token),
// errors as ApiError {status, code, message, field} taken from the API's error body, and one
// shared EventSource on /api/events that hands job events to whoever subscribed.

const TOKEN_KEY = 'ipsd.token';

export class ApiError extends Error {
    constructor(status, code, message, field) {
        super(message);
        this.name = 'ApiError';
        this.status = status;
        this.code = code;
        this.field = field || null;
    }
}

export function getToken() {
    try {
        return localStorage.getItem(TOKEN_KEY) || '';
    } catch {
        return '';
    }
}

export function setToken(token) {
    try {
        if (token) localStorage.setItem(TOKEN_KEY, token);
        else localStorage.removeItem(TOKEN_KEY);
    } catch {
        /* storage disabled: the token lasts for this page only */
    }
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
    if (token && method !== 'GET') headers.Authorization = `Bearer ${token}`;
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
        throw new ApiError(res.status, e?.code || `http_${res.status}`,
            e?.message || `${res.status} ${res.statusText}`, e?.field);
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

function connect() {
    source = new EventSource('/api/events');
    source.onopen = () => setStatus('live');
    source.onerror = () => setStatus(source.readyState === EventSource.CLOSED ? 'closed'
        : 'reconnecting');
    source.addEventListener('job', (ev) => {
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
    if (!source) connect();
    listeners.add(fn);
    return () => listeners.delete(fn);
}

// Calls fn({state, received, malformed}) when the stream's state changes.
export function onEventStatus(fn) {
    if (!source) connect();
    statusListeners.add(fn);
    fn(stats);
    return () => statusListeners.delete(fn);
}
