// fit_stored.js: the map a fit stores as its pixel's calibration (docs/api.md "Fits", the request's
// "map": recommended, shrunk or kriged), which the Fit view shows first: which map it is, its grid
// S and S_err (and the resolution error S_res where known), and one sentence on how it was made;
// also the sentence the Pixel view gives for a calibration made from a fit.
//
// Which map the fit offers: the pixel's current calibration when it is this fit's (its `map`, and
// its id for the sentence), else the fit record's `calibration.map`. Fits read from servers that
// did not give that word are told, in order, by the fit's job (its params record "map" when not
// recommended; the result then has that map, else the server stored the recommended one) and
// last by the grid itself (r equal to the kriged map's grid and not the recommended r: kriged;
// else recommended). The map's numbers are the fit result's own (the same numbers the
// calibration stores: srv_fit.c keep_map).
import { get } from './api.js';
import { fmt, h } from './dom.js';
import { cellSource, mapFigure } from './calib_maps.js';
import { valueTable } from './charts.js';
import { errFigure, resFigure } from './fit_maps.js';

const JOB_PAGES = 5; // pages of 1000 fit jobs searched for a fit's job at most

// The map the server stores when `asked` is requested of a fit with result res (srv_fit.c: the
// recommended map when the result lacks the one asked for).
function offered(asked, res, c) {
    const kr = res.kriged_map;
    if (asked === 'kriged' && kr && Array.isArray(kr.S) && (!c || c.r === kr.grid)) return 'kriged';
    if (asked === 'shrunk' && res.shrunk_map && Array.isArray(res.shrunk_map.S)) return 'shrunk';
    return 'recommended';
}

// The fit's job (GET /api/jobs?kind=fit, of its scan when it has one): the one whose fit_id, or
// whose fit_ids (a job of every pixel), names the fit; null when not found.
async function fitJob(fit) {
    const scan = fit.scan_id ? `&scan=${fit.scan_id}` : '';
    for (let page = 0; page < JOB_PAGES; page++) {
        const p = await get(`/api/jobs?kind=fit${scan}&limit=1000&offset=${page * 1000}`);
        const j = p.items.find((x) => x.fit_id === fit.id ||
            (Array.isArray(x.fit_ids) && x.fit_ids.includes(fit.id)));
        if (j) return j;
        if ((page + 1) * 1000 >= p.total) break;
    }
    return null;
}

// Which map fit offers as its calibration: {kind: 'recommended' | 'shrunk' | 'kriged' | null
// (none offered), source: 'calibration' | 'fit' | 'job' | 'grid' | 'none', cal (the calibration,
// when its source), job}.
export async function storedKind(fit) {
    const c = fit.calibration, res = fit.result || {};
    if (!c) return { kind: null, source: 'none' };
    if (c.current && c.current_calibration_id) {
        const cal = await get(`/api/calibrations/${c.current_calibration_id}`).catch(() => null);
        if (cal && cal.fit_id === fit.id && cal.map) return { kind: cal.map, source: 'calibration', cal };
    }
    if (c.map) return { kind: c.map, source: 'fit' }; // the fit's record (servers since schema 8)
    const job = await fitJob(fit).catch(() => null);
    if (job) return { kind: offered(job.params?.map ?? 'recommended', res, c), source: 'job', job };
    const kr = res.kriged_map;
    const grid = kr && Array.isArray(kr.S) && c.r === kr.grid && c.r !== res.recommended_r;
    return { kind: grid ? 'kriged' : 'recommended', source: 'grid' };
}

// The recommended r (the best BIC for fits stored before it existed).
export const recommendedR = (res) => (res.recommended_r !== undefined ? res.recommended_r
    : res.best_r?.bic);

// The numbers of map kind of result res: {kind, r, S, S_err, S_res (null: not known), fit (the
// recommended r's sweep entry: its status, chi2, I0 are the calibration's)}; null when the result
// has no such map.
export function storedMap(res, kind) {
    const rec = recommendedR(res);
    const f = (res.fits || []).find((x) => x.r === rec);
    if (!f || !Array.isArray(f.S)) return null;
    const sh = res.shrunk_map && Array.isArray(res.shrunk_map.S) ? res.shrunk_map : null;
    const sRes = sh && sh.r === f.r && Array.isArray(sh.S_res) ? sh.S_res : null;
    if (kind === 'kriged') {
        const kr = res.kriged_map;
        if (!kr || !Array.isArray(kr.S)) return null;
        return { kind, r: kr.grid, S: kr.S, S_err: kr.S_err, S_res: null, fit: f, kr };
    }
    if (kind === 'shrunk') {
        return sh ? { kind, r: sh.r, S: sh.S, S_err: sh.S_err, S_res: sRes, fit: f, sh } : null;
    }
    return { kind: 'recommended', r: f.r, S: f.S, S_err: f.S_err, S_res: sRes, fit: f };
}

// "the 2 × 2 and 4 × 4 grids"
function gridList(levels) {
    const g = levels.map((l) => `${l.q} × ${l.q}`);
    if (!g.length) return '';
    const words = g.length === 1 ? g[0] : `${g.slice(0, -1).join(', ')} and ${g[g.length - 1]}`;
    return `the ${words} grid${g.length > 1 ? 's' : ''}`;
}

// One sentence on how map m (storedMap's) of result res was made.
export function mapSentence(res, m) {
    const n = res.N ?? res.n_points;
    const from = Number.isFinite(n) ? ` from ${n} points` : '';
    if (m.kind === 'kriged') {
        const kr = m.kr, grids = gridList(kr.levels || []);
        const smooth = `a smooth part (amplitude ${fmt(kr.amplitude, 2)}, correlation length ` +
            `${fmt(kr.length_um, 2)} µm)`;
        const parts = kr.smooth ? (grids ? `${smooth} plus ${grids}` : smooth)
            : `${grids || 'a flat map'} alone, without a smooth part (its likelihood ratio ` +
                `${fmt(kr.likelihood_ratio, 3)} too small to keep it)`;
        return `Kriged map on a ${kr.grid} × ${kr.grid} grid${from}: ${parts}; S_err is the ` +
            (kr.smooth ? 'posterior standard deviation.' : 'smooth model\'s posterior spread ' +
                'about the map (the grids alone see nothing inside their cells).');
    }
    const why = res.recommended_reason ?? 'the best BIC (this fit was stored before ipsd gave ' +
        'its reasons)';
    const sRes = m.S_res ? '; S_res, its resolution error (structure finer than the grid), ' +
        'adds to it in quadrature' : '';
    if (m.kind === 'shrunk') {
        return `Shrunk map: the paper's r = ${m.r} map (the recommended r, least squares${from}) ` +
            `with its detail over r = ${m.sh.toward_r} shrunk where it does not stand above its ` +
            `noise (${fmt(100 * m.sh.factor, 2)} % of it kept); S_err is the posterior standard ` +
            `deviation (its noise and the shrinkage's expected bias)${sRes}.`;
    }
    return `The paper's r = ${m.r} map (least squares${from}), the recommended r: ${why}; ` +
        `S_err is its 1σ least-squares error${sRes}.`;
}

// Why no kriged map could be made, when the result says so (kriged_map {"error"}).
export const krigedWhyNot = (res) => (res.kriged_map && typeof res.kriged_map.error === 'string'
    ? `No kriged map could be made: ${res.kriged_map.error}.` : null);

const KIND_TITLE = { recommended: 'Recommended map', shrunk: 'Shrunk map', kriged: 'Kriged map' };
export const kindTitle = (kind) => KIND_TITLE[kind] || 'Map';

// The Fit view's first section's content: which map the fit stores (info: storedKind's answer),
// the sentence, and the map's figures (testids plot-stored, plot-stored-Serr, plot-stored-Sres).
export function storedContent(fit, info, pitch) {
    const res = fit.result || {};
    // the server's own sentence when the stored map is not the one asked for (stored_map.why, the
    // calibration's map_note), else the result's reason why no kriged map could be made
    const whyNot = res.stored_map?.why ?? krigedWhyNot(res);
    const noKriged = whyNot && info.kind !== 'kriged'
        ? [' ', h('span', { 'data-testid': 'stored-no-kriged' }, whyNot)] : [];
    const source = {
        calibration: `the pixel's calibration #${info.cal?.id} holds it`,
        fit: 'as the fit\'s record says; it is not the pixel\'s current calibration',
        job: `the map the fit's request, job #${info.job?.id}, asked for`,
        grid: 'told from its grid: neither a calibration nor the job of this fit was found',
    }[info.source];
    const m = info.kind ? storedMap(res, info.kind) : storedMap(res, 'recommended');
    if (!m) {
        return [h('p', { 'data-testid': 'stored-sentence', dataset: { map: 'none' } },
            'This fit has no map to store as a calibration (no admissible map: see each ' +
            'fit\'s status under Comparison).', ...noKriged)];
    }
    const sentence = h('p', { class: 'lead', 'data-testid': 'stored-sentence',
        dataset: { map: info.kind ?? 'none', source: info.source } },
    info.kind ? mapSentence(res, m) : 'This fit stores no calibration (an uploaded scan file ' +
        'without a sensor pixel). The map it recommends: ' +
        mapSentence(res, m).replace(/^The /, 'the '), ...noKriged);
    const f = m.fit;
    const facts = h('p', { class: 'muted small', 'data-testid': 'stored-facts' },
        info.kind ? `The map this fit offers as its pixel's calibration (${source}). ` : '',
        `Fit status ${f.status}, χ²/dof ${fmt(f.chi2_red)}, I₀ = ${fmt(f.I0, 6)} DN ` +
        `(the recommended r = ${f.r}'s fit${m.kind === 'recommended' ? '' : ', which the ' +
            'calibration records with this map'}).`);
    const map = mapFigure(cellSource('stored', m.S, m.r, pitch, m.S_err), pitch, 'plot-stored',
        `${kindTitle(m.kind)} S (${m.r}×${m.r})`);
    if (m.r * m.r <= 400) map.append(valueTable(m.S, m.r, m.r));
    return [sentence, facts, h('div', { class: 'maps' }, map,
        Array.isArray(m.S_err) ? errFigure(m, pitch, 'plot-stored-Serr') : null,
        m.S_res ? resFigure(m.S_res, m.r, pitch, 'plot-stored-Sres') : null)];
}
