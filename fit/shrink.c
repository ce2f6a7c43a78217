/* shrink.c: the shrunk map (see shrink.h). */
#include "fit/shrink.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void fit_grid_overlap(int r, int q, double *w)
{
    for (int a = 0; a < r; a++)
        for (int b = 0; b < q; b++) {
            /* cells [a/r, (a+1)/r) and [b/q, (b+1)/q) of the unit pitch; the fraction of the
             * fine cell (width 1/r) the overlap covers */
            double lo = fmax((double)a / r, (double)b / q);
            double hi = fmin((double)(a + 1) / r, (double)(b + 1) / q);
            w[a * q + b] = hi > lo ? (hi - lo) * r : 0;
        }
}

/* out (r x r) = W v W^T for a q x q map v: the map averaged over each fine cell's area. */
static void project(const double *v, int q, const double *w, int r, double *out)
{
    for (int j = 0; j < r; j++)
        for (int i = 0; i < r; i++) {
            double s = 0;
            for (int l = 0; l < q; l++) {
                if (w[j * q + l] == 0) continue;
                for (int k = 0; k < q; k++) s += w[j * q + l] * w[i * q + k] * v[l * q + k];
            }
            out[j * r + i] = s;
        }
}

int fit_shrink(const fit_result_t *fine, const fit_result_t *coarse, double noise_scale,
               fit_shrunk_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    if (!fine->S || !fine->S_err || !coarse->S || !coarse->S_err)
        return err_set(err, -EINVAL, "shrinking needs both fits' maps");
    int r = fine->r, q = coarse->r;
    if (r < 2 || q < 1 || q >= r)
        return err_set(err, -EINVAL, "shrinking needs a coarser fit (r = %d toward %d)", r, q);
    size_t d = (size_t)r * r;
    double *w = malloc(sizeof(double) * (size_t)r * q);
    double *Sp = malloc(sizeof(double) * d), *Ep = malloc(sizeof(double) * d);
    out->S = malloc(sizeof(double) * d);
    out->S_err = malloc(sizeof(double) * d);
    if (!w || !Sp || !Ep || !out->S || !out->S_err) {
        free(w), free(Sp), free(Ep);
        fit_shrunk_free(out);
        return err_set(err, -ENOMEM, "out of memory");
    }
    fit_grid_overlap(r, q, w);
    project(coarse->S, q, w, r, Sp);
    project(coarse->S_err, q, w, r, Ep); /* sum of weighted sigmas: a bound (correlation <= 1) */
    double dd = 0, v = 0;
    for (size_t j = 0; j < d; j++) {
        double e = fine->S_err[j] * noise_scale;
        dd += (fine->S[j] - Sp[j]) * (fine->S[j] - Sp[j]);
        v += e * e;
    }
    /* positive-part James-Stein: c = max(0, 1 - (d - 2) sigma^2 / |D|^2), sigma^2 = v / d */
    double c = dd > 0 ? fmax(0, 1 - ((double)d - 2) * (v / (double)d) / dd) : 0;
    for (size_t j = 0; j < d; j++) {
        out->S[j] = Sp[j] + c * (fine->S[j] - Sp[j]);
        out->S_err[j] = c * fine->S_err[j] + (1 - c) * Ep[j];
    }
    out->r = r;
    out->toward_r = q;
    out->factor = c;
    out->detail = sqrt(dd / (double)d);
    out->noise = sqrt(v / (double)d);
    free(w), free(Sp), free(Ep);
    return 0;
}

int fit_shrink_recommended(const fit_sweep_t *sw, double noise_scale, fit_shrunk_t *out,
                           err_t *err)
{
    memset(out, 0, sizeof *out);
    int r = sw->recommended_r;
    if (r < 2 || r - 1 < sw->r_min || r > sw->r_max) return 0;
    const fit_result_t *fine = &sw->fits[r - sw->r_min], *coarse = fine - 1;
    if (!fine->S || !fine->S_err || !coarse->S || !coarse->S_err) return 0;
    return fit_shrink(fine, coarse, noise_scale, out, err);
}

void fit_shrunk_free(fit_shrunk_t *s)
{
    if (!s) return;
    free(s->S);
    free(s->S_err);
    s->S = s->S_err = NULL;
    s->r = 0;
}
