/* stop.h: a caller's stop poll for fit/'s long loops (the design matrix's batches, the solves of
 * each r, the LM iterations of the paper's fit and of the geometry fit). The caller gives a
 * function and its argument (say, one that reads its own atomic flag); the loops call it at their
 * heads and, when it answers nonzero, unwind with -ECANCELED, freeing what they hold. fit/ keeps
 * no state of its own: no globals, the poll runs on the caller's thread. A zeroed fit_stop_t
 * (the options' defaults) never stops, and then a poll costs one branch. */
#ifndef IPSD_FIT_STOP_H
#define IPSD_FIT_STOP_H

typedef struct fit_stop {
    int (*poll)(void *arg); /* nonzero: stop now; NULL: never stop */
    void *arg;
} fit_stop_t;

/* Whether s asks the running fit to stop. */
static inline int fit_stop_now(const fit_stop_t *s)
{
    return s->poll && s->poll(s->arg);
}

#endif
