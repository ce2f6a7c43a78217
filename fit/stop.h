/* stop.h: a caller's stop poll for fit/'s long loops (the design matrix's batches, the solves of
 * each r, the non-negative solve's active-set steps, the LM iterations of the paper's fit and of
 * the geometry fit, the Wiener baseline's kernel and FFT passes). The caller gives a
 * function and its argument (say, one that reads its own atomic flag); the loops call it at their
 * heads and, when it answers nonzero, unwind with -ECANCELED, freeing what they hold. fit/ keeps
 * no state of its own: no globals, the poll runs on the caller's thread. A zeroed fit_stop_t
 * (the options' defaults) never stops, and then a poll costs one branch.
 *
 * A caller that wants to know where a poll is (a test hook that holds a fit inside one loop)
 * gives poll_at as well: the polls of a named place (FIT_STOP_SITE_*) call it with that name
 * instead of poll. */
#ifndef IPSD_FIT_STOP_H
#define IPSD_FIT_STOP_H

/* The named places (fit_stop_at's site). */
#define FIT_STOP_SITE_LM "lm" /* inside the LM (lm.c): each residual, Jacobian and iteration */
#define FIT_STOP_SITE_NNLS "nnls"         /* inside the non-negative solve (wls.c): each active-set
                                             step, outer and inner, before its solve */
#define FIT_STOP_SITE_WIENER "wiener"     /* inside the Wiener baseline (wiener.c): each row of
                                             the kernel, each pass of the FFTs and the filter */
#define FIT_STOP_SITE_GEOMETRY "geometry" /* inside the geometry fit (geometry.c): each
                                             iteration, residual and covariance column */

typedef struct fit_stop {
    int (*poll)(void *arg); /* nonzero: stop now; NULL: never stop */
    void *arg;
    /* optional: the same answer, told the place; NULL: fit_stop_at calls poll */
    int (*poll_at)(void *arg, const char *site);
} fit_stop_t;

/* Whether s asks the running fit to stop. */
static inline int fit_stop_now(const fit_stop_t *s)
{
    return s->poll && s->poll(s->arg);
}

/* The same at the named place site (a FIT_STOP_SITE_*). */
static inline int fit_stop_at(const fit_stop_t *s, const char *site)
{
    return s->poll_at ? s->poll_at(s->arg, site) : fit_stop_now(s);
}

#endif
