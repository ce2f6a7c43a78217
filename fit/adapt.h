/* adapt.h: where an adaptive scan looks next. Given the posterior covariance Sigma of the pixel's
 * fine cells (the kriged map's, krige.h) and candidate spot positions, each a row a_j of the fine
 * grid's design (design.h: the spot's integral over each cell) with the variance s_j^2 of its
 * measurement, fit_adapt_pick chooses a batch greedily: each pick the candidate whose measurement
 * most reduces the integrated posterior variance over the pixel (the trace of Sigma, the cells
 * having equal areas),
 *     gain_j = |Sigma a_j|^2 / (a_j^T Sigma a_j + s_j^2),
 * then Sigma becomes the posterior after that measurement (the Gaussian update of one linear
 * observation),
 *     Sigma <- Sigma - g g^T / (a_j^T g + s_j^2),   g = Sigma a_j,
 * before the next pick. The measurements' values are not needed: a Gaussian posterior's
 * covariance does not depend on them. Greedy is within a factor (1 - 1/e) of the best batch for
 * this objective when it is submodular (Krause, Singh & Guestrin 2008).
 *
 * Cost: one product A Sigma (candidates x cells x cells), then candidates x cells a pick (the
 * update is carried in G = A Sigma, never in Sigma itself). Pure, thread-safe. */
#ifndef IPSD_FIT_ADAPT_H
#define IPSD_FIT_ADAPT_H

#include <stddef.h>

#include "base/err.h"

/* Picks up to batch distinct candidates of nc (rows of A, nc x m row-major; noise variances s2,
 * nc, > 0 or 0 for an exact measurement) under the prior covariance Sigma (m x m, symmetric
 * positive semi-definite, row-major). picked (batch) gets their indices in the order chosen;
 * mean_var (batch + 1, may be NULL) the mean posterior variance over the m cells before the first
 * pick and after each. Returns the number picked (fewer than batch when no candidate is left that
 * reduces the variance), or -EINVAL / -ENOMEM with err. */
int fit_adapt_pick(size_t m, const double *Sigma, size_t nc, const double *A, const double *s2,
                   int batch, int *picked, double *mean_var, err_t *err);

#endif
