// scan_state.js: what the Scans list and the Scan view share about a scan's state: which states
// are active, how often the views re-read active scans, a sensor's name, and the progress cell
// (bar, points done of the total, the ETA or the phase while it runs).
import { fmtDuration, h } from './dom.js';

export const ACTIVE = new Set(['queued', 'running']);
export const POLL_MS = 5000; // re-read active scans now and then: events can be missed or damaged

export function sensorName(s) {
    return s ? `#${s.id} ${s.model} ${s.serial}` : '?';
}

export function progressCell(p) {
    const bar = h('progress', { max: 1, value: p.progress ?? 0 });
    const text = h('span', { class: 'prog-text' });
    const cell = h('td', { class: 'progress' }, bar, text);
    setProgress(cell, p);
    return cell;
}

// Updates a progress cell from a scan or a job event {state, progress, points_done,
// points_total, eta_s}.
export function setProgress(cell, p) {
    const bar = cell.querySelector('progress'), text = cell.querySelector('.prog-text');
    bar.value = p.progress ?? 0;
    const pct = Math.round(100 * (p.progress ?? 0));
    bar.setAttribute('aria-label', `${pct} % done`);
    let s = `${p.points_done ?? 0} / ${p.points_total ?? p.raster?.points_total ?? '?'}`;
    if (p.state === 'running' && Number.isFinite(p.eta_s)) s += ` · ETA ${fmtDuration(p.eta_s)}`;
    else if (p.state === 'running' && p.phase && p.phase !== 'raster') s += ` · ${p.phase}`;
    text.textContent = s;
}
