// fit_select.js: the Fit view's model selection (Plotly.js, charts.js): AIC and BIC against r
// beside chi2 and the leave-one-out cross-validation chi2 (fits[].cv_chi2, when the document has
// it), the best r of each criterion emphasised and the recommended r (fit/recommend.h) drawn as
// a dashed line on both with the fit's recommended_reason in words under them; and the goodness
// of fit of one map in words (fits[].chi2_p: the chi-square p-value under the noise model; status
// poor_fit below 1e-3, docs/contracts.md).
import { fmt, h } from './dom.js';
import { plotFigure } from './charts.js';

export const POOR_FIT_P = 1e-3; // fit/model.h FIT_POOR_FIT_P

const finite = (v) => v !== null && v !== undefined && Number.isFinite(v);

// A line of one criterion against r (the r without a value left out), best r a larger marker.
function series(fits, key, name, color, best, axis, dash) {
    const pts = fits.filter((f) => finite(f[key]));
    return { type: 'scatter', mode: 'lines+markers', name, x: pts.map((f) => f.r),
        y: pts.map((f) => f[key]), xaxis: `x${axis}`, yaxis: `y${axis}`,
        line: { color, dash: dash || 'solid', width: 2 },
        marker: { color, size: pts.map((f) => (f.r === best ? 13 : 7)),
            symbol: pts.map((f) => (f.r === best ? 'star' : 'circle')) },
        hovertemplate: `${name} at r = %{x}: %{y:.6g}<extra></extra>` };
}

// The model-selection figure: AIC/BIC (left) and chi2 / CV chi2 (right, log scale) against r,
// the recommended r rec marked on both (a dashed line named 'recommended').
export function selectionFigure(res, rec) {
    const fits = res.fits || [], best = res.best_r || {};
    const hasCv = fits.some((f) => finite(f.cv_chi2));
    // colour-blind safe pair (Okabe-Ito blue and vermillion), grey for chi2
    const data = [
        series(fits, 'aic', 'AIC', '#0072b2', best.aic, ''),
        series(fits, 'bic', 'BIC', '#d55e00', best.bic, ''),
        series(fits, 'chi2', 'χ²', '#555555', null, 2),
        hasCv ? series(fits, 'cv_chi2', 'cross-validation χ²', '#009e73', null, 2, 'dot') : null,
    ].filter(Boolean);
    const rs = fits.map((f) => f.r);
    const xr = [Math.min(...rs) - 0.5, Math.max(...rs) + 0.5];
    const axes = (k, domain, ytitle, log, ydomain = [0, 1]) => ({
        [`xaxis${k}`]: { title: { text: 'sub-pixels per axis r' }, domain, range: xr, dtick: 1,
            anchor: `y${k}` },
        [`yaxis${k}`]: { title: { text: ytitle }, type: log ? 'log' : 'linear', anchor: `x${k}`,
            domain: ydomain },
    });
    const mark = (k) => ({ type: 'line', name: 'recommended', xref: `x${k}`, yref: `y${k} domain`,
        x0: rec, x1: rec, y0: 0, y1: 1, line: { color: '#cc79a7', width: 2, dash: 'dash' } });
    const label = (k) => ({ text: `recommended r = ${rec}`, xref: `x${k}`, yref: `y${k} domain`,
        x: rec, y: 0.98, yanchor: 'top', xanchor: 'right', showarrow: false,
        font: { size: 11, color: '#a0507f' } });
    const layout = { ...axes('', [0, 0.44], 'AIC, BIC'),
        ...axes(2, [0.58, 1], hasCv ? 'χ², CV χ² (log)' : 'χ² (log)', true),
        shapes: finite(rec) ? [mark(''), mark(2)] : [],
        annotations: finite(rec) ? [label(''), label(2)] : [],
        legend: { orientation: 'h', y: -0.25 }, margin: { l: 60, r: 20, t: 30, b: 80 } };
    const stacked = { height: 620, layout: { ...axes('', [0, 1], 'AIC, BIC', false, [0.6, 0.95]),
        ...axes(2, [0, 1], layout.yaxis2.title.text, true, [0.1, 0.45]),
        legend: { orientation: 'h', y: -0.12 } } };
    return plotFigure({ title: 'Model selection against r', testid: 'plot-selection', data,
        layout, height: 360, name: 'model-selection', stacked,
        note: 'Stars: the smallest AIC and the smallest BIC. ' + (hasCv ? 'The cross-validation ' +
            'χ² is the leave-one-out prediction error of each r (smaller predicts better). '
            : '') + 'Dashed: the recommended r.' });
}

// The recommended r and its reason, in words.
export function reasonText(res, rec) {
    if (!finite(rec)) return 'No r is recommended: no map of this fit can be trusted.';
    return `Recommended r = ${rec}` + (res.recommended_reason ? `: ${res.recommended_reason}`
        : ' (the best BIC: this fit was stored before ipsd gave its reasons).');
}

// The goodness of fit of map f in words (its chi-square p-value under the noise model).
export function goodness(f) {
    const p = f.chi2_p;
    const stat = `χ²/dof = ${fmt(f.chi2_red)}`;
    if (!finite(p)) {
        return { cls: 'muted', poor: null, text: `No p-value (${stat}): no degrees of freedom ` +
            'left, or a fit stored before p-values were kept.' };
    }
    const ps = p < 1e-4 ? p.toExponential(1) : fmt(p, 3);
    if (p < POOR_FIT_P || f.status === 'poor_fit') {
        return { cls: 'warn', poor: true, text: `Poor fit (p = ${ps}, ${stat}): a χ² this ` +
            `large would happen by chance less than once in ${Math.round(1 / POOR_FIT_P)} ` +
            'fits if the model held, so the model does not describe these data within their ' +
            'noise (status poor_fit). Look for a pattern in the residuals.' };
    }
    return { cls: 'ok', poor: false, text: `Good fit (p = ${ps}, ${stat}): the residuals are ` +
        'consistent with the noise model.' + (p > 0.999 ? ' (A p this close to 1 can mean ' +
        'the noise is overestimated.)' : '') };
}
