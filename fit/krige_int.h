/* krige_int.h (internal to fit/): the kriged map's restricted-likelihood problem (krige.h), shared
 * by krige.c (set-up, the two models, the test between them), krige_lik.c (the likelihood, its
 * gradient and average information, in the points' space or in the fine cells' space),
 * krige_opt.c (its maximisation) and krige_post.c (the posterior map).
 *
 * The model: d = mu 1_A + A u + sum_j A_j v_j + e, u ~ N(0, I0^2 e^th_s K(l)) on the F x F fine
 * cells, v_j ~ N(0, I0^2 e^th_j I) on grid q_j's cells, e ~ N(0, D), mu flat. theta holds
 * (th_1 .. th_nl, [th_s, log l]). Two ways to the same numbers:
 *   - points' space: V = D + sum_j e^th_j M_j + e^th_s M_s(l), M = I0^2 A_. A_.^T, one n x n
 *     factorisation; M_s through K's closed-form factor (krige_kernel.h);
 *   - cells' space (Henderson's mixed-model equations): C = H + blockdiag(0, e^-th_s K^-1,
 *     e^-th_j I), H = W^T D^-1 W, W = [1_A, I0 A, I0 A_j], one p x p factorisation,
 *     p = 1 + F^2 + sum q_j^2, whatever n: -2 log L = log|D| + log|Sigma| + log|C| + d^T D^-1 d
 *     - h^T C^-1 h, h = W^T D^-1 d.
 * krige.c picks the cheaper per model. */
#ifndef IPSD_FIT_KRIGE_INT_H
#define IPSD_FIT_KRIGE_INT_H

#include <stddef.h>

#include "fit/krige.h"
#include "fit/stop.h"
#include "krige_kernel.h"

#define KR_MAX_THETA (FIT_KRIGE_MAX_LEVELS + 2)

typedef struct kr_prob {
    /* the data and the model (set by krige.c) */
    size_t n, m;            /* points, fine cells F^2 */
    int F;
    const double *d, *s2;   /* signal - bias, sigma^2 */
    const double *A;        /* n x m: the fine grid's design */
    const double *one;      /* n: A 1, the mean's column */
    double I0;              /* the scale of the variances */
    int nl;                 /* grid levels */
    int q[FIT_KRIGE_MAX_LEVELS];
    const double *Aq[FIT_KRIGE_MAX_LEVELS]; /* n x q^2: grid q's own design */
    const double *Mq[FIT_KRIGE_MAX_LEVELS]; /* n x n: I0^2 A_q A_q^T (points' space only) */
    int smooth;             /* the model has the smooth part */
    int cells;              /* evaluated in the cells' space */
    const fit_stop_t *stop;
    int evals, stopped, failed;

    kr_kernel_t ker;        /* the smooth part's kernel at the last l asked for */
    /* points' space */
    double *W, *Wd;         /* n x m: L^T a_p L of each point's image, d / d log l */
    double *Ms, *Msd;       /* n x n: I0^2 W W^T and d / d log l */
    double l_ms, l_msd;     /* the l of Ms and of Msd (NaN: none) */
    double *V, *Vi;         /* n x n: V; its Cholesky factor, then (kr_derivs) its inverse */
    double *Py, *Vone, *Vd; /* n: P d, V^-1 1_A, V^-1 d */
    double a;               /* 1_A^T V^-1 1_A */
    /* cells' space */
    size_t p;               /* 1 + (smooth ? m : 0) + sum q^2 */
    size_t off_s, off_q[FIT_KRIGE_MAX_LEVELS]; /* column offsets of the blocks in W */
    double *H, *h;          /* p x p, p */
    double dDd, logdetD;
    double *C, *Ci, *chat;  /* p x p factor, p x p inverse (kr_derivs), p: C^-1 h */
    double *t, *y;          /* scratch: p x KR_MAX_THETA each */

    double mu;              /* the mean's estimate at the last evaluation */
    double dPd;             /* and d^T P d there: the data's distance from the model, whose
                               expectation under the model is n - 1 (tr P V) */
    int at_valid;           /* the state above belongs to the theta of the last kr_value */
    double at[KR_MAX_THETA];
} kr_prob_t;

/* The two models of one scan and prior (with the smooth part and without), set up as
 * fit_krige_with does; force_cells: 0 or 1 puts both in the points' or the cells' space, -1
 * lets each take the cheaper. 0, -EINVAL, -ENOMEM with err. */
typedef struct kr_work kr_work_t;
int kr_work_new(const fit_scan_t *scan, const fit_krige_prior_t *pr, const fit_options_t *opts,
                int force_cells, kr_work_t **out, err_t *err);
kr_prob_t *kr_work_model(kr_work_t *w, int smooth);
const double *const *kr_work_spread(const kr_work_t *w); /* the grids' Bq, for kr_posterior */
void kr_work_free(kr_work_t *w);

/* Allocates the state for the model set in k (n, m, F, nl, q, smooth, cells) and, in the cells'
 * space, builds H and h. 0 or -ENOMEM. */
int kr_prob_init(kr_prob_t *k);
void kr_prob_free(kr_prob_t *k);

/* The number of hyperparameters and the bounds of each. */
int kr_theta_count(const kr_prob_t *k);
void kr_theta_bounds(const kr_prob_t *k, int i, double *lo, double *hi);

/* -log L (restricted, up to a constant; the same in both spaces) at theta; HUGE_VAL when V or C
 * is not positive definite or a stop was asked for (k->stopped). Keeps the factorisation. */
double kr_value(kr_prob_t *k, const double *th);

/* After kr_value at the same theta: the gradient of -log L (g) and its average information
 * (AI, np x np: half the expected Hessian's data part, (1/2) (V_i P d)^T P (V_j P d)). Leaves
 * the inverse (Vi or Ci) for the posterior. 0, or -1 when the inverse failed. */
int kr_derivs(kr_prob_t *k, const double *th, double *g, double *AI);

/* Maximises the likelihood from start (np values): damped Fisher scoring with the average
 * information, within the bounds. th gets the best point; returns -log L there (HUGE_VAL: none
 * found). The state is left at th. */
double kr_maximise(kr_prob_t *k, const double *start, double *th);

/* The best of krige.c's n_starts starting points (1 or 2) for the model in k: th gets its optimum
 * and the state is left there (value and derivatives). Returns -log L there (HUGE_VAL: none). */
double kr_best_of_starts(kr_prob_t *k, int n_starts, double *th);

/* The posterior mean and standard deviation of S = T / mean T on the fine cells at th (after
 * kr_value and kr_derivs there), into S and S_err (m each). Bq: per level, m x q^2, the
 * fraction of each fine cell in each of the grid's cells. 0, -ENOMEM, -EDOM. */
int kr_posterior(kr_prob_t *k, const double *th, const double *const *Bq, double *S,
                 double *S_err);

/* The same posterior's whole covariance of S, m x m row-major (its diagonal S_err^2), into
 * S_cov; S gets the mean as above. The same preconditions and returns. */
int kr_posterior_cov(kr_prob_t *k, const double *th, const double *const *Bq, double *S,
                     double *S_cov);

#endif
