/* geometry_pick.c: the geometry fit's r picked from the data (geometry.h, fit_geometry_pick):
 * the geometry fitted at increasing r, kept at the smallest BIC = n ln(chi2/n) + (r*r + 3) ln n.
 *
 * Why: R, dx, dy are identified by the pixel's edges, and an r x r map too coarse for the
 * pixel's own edge structure lets the radius and the offset absorb the misfit (a 13 x 13 scan of
 * the paperlike scene at r = 5: R 1.73 +- 0.006 um against the true 1.40, chi2_red 7.8). Adding
 * sub-pixels lowers chi2 until the map holds the structure; BIC then turns up, since it charges
 * ln n per parameter. It uses ln chi2, so the noise model's scale (the paper's sigma is sqrt(G)
 * too large) does not change the pick. Measured in docs/numerics.md, "Geometry fit". */
#include <errno.h>
#include <math.h>

#include "fit/geometry.h"

int fit_geometry_pick(const fit_scan_t *scan, const fit_options_t *opts, fit_geometry_t *out,
                      err_t *err)
{
    fit_geometry_t best = {0}, g;
    int have = 0, worse = 0, first = FIT_GEOMETRY_PICK_R_MIN, last = 0, rc = 0;
    for (int r = first; r <= FIT_GEOMETRY_PICK_R_MAX; r++) {
        err_t e;
        /* too few degrees of freedom left (the first fit counted the points): it wanders */
        if (r > first && (double)best.n_used - (r * r + 3) < (double)best.n_used / FIT_GEOMETRY_DOF_DIV)
            break;
        rc = fit_geometry_run(scan, r, opts, &g, &e);
        if (rc == -ERANGE && r > first) break;
        if (rc) {
            err_set(err, rc, "%s", e.msg);
            return rc;
        }
        last = r;
        if (g.flags & FIT_GEOMETRY_UNUSABLE) {
            if (!have) best = g;
            continue;
        }
        if (have && !(g.bic < best.bic)) {
            if (++worse > FIT_GEOMETRY_PICK_PATIENCE) break; /* BIC turned up and stayed up */
            continue;
        }
        best = g, have = 1, worse = 0;
    }
    *out = best;
    out->r_picked = 1, out->r_first = first, out->r_last = last;
    return 0;
}
