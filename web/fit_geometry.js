// fit_geometry.js: the Fit view's facts on the geometry fitted before the maps (the result's
// geometry, docs/contracts.md): the spot radius and the scan-grid offset with their 1-sigma, the
// model that made them (refined under the kriged model, or the r × r map's) and its status.
import { h } from './dom.js';

const um = (v) => (Number.isFinite(Number(v)) ? Number(v).toFixed(4) : '–');
const pm = (v, e) => `${um(v)} ± ${um(e)} µm`;

// dt/dd pairs for the Result panel's list; none when the fit has no geometry.
export function geometryFacts(g) {
    if (!g) return null;
    if (g.error) return [h('dt', {}, 'Geometry'),
        h('dd', { class: 'err', 'data-testid': 'geometry-error' }, g.error)];
    const how = g.model === 'kriged' ? 'refined under the kriged model' : 'the r × r map\'s';
    const why = g.kriged_fit?.error ? ` (the kriged refinement: ${g.kriged_fit.error})` : '';
    return [
        h('dt', {}, 'Spot radius'),
        h('dd', { 'data-testid': 'geometry-R', dataset: { value: g.spot_radius_um } },
            `${pm(g.spot_radius_um, g.spot_radius_um_err)} (written ${um(g.written_spot_radius_um)})`),
        h('dt', {}, 'Grid offset'),
        h('dd', { 'data-testid': 'geometry-offset' },
            `dx ${pm(g.dx_um, g.dx_um_err)}, dy ${pm(g.dy_um, g.dy_um_err)}`),
        h('dt', {}, 'Geometry'),
        h('dd', { class: g.status === 'ok' ? '' : 'warn', 'data-testid': 'geometry-model',
            dataset: { model: g.model ?? 'map', status: g.status } },
        `${how}, r = ${g.r}, ${g.status}${why}`),
    ];
}
