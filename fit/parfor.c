/* parfor.c: iterations on a few threads (parfor.h). The iterations are claimed one at a time
 * under a mutex: there are tens of them (the r of a sweep), each milliseconds to seconds long. */
#include "parfor.h"

#include <pthread.h>

struct parfor {
    pthread_mutex_t mu;
    int next, n;          /* the next iteration to start, of n */
    int failed_i, rc;     /* the failed iteration of smallest i (n: none) and its return */
    int (*body)(int, int, void *);
    void *ctx;
};

struct worker {
    struct parfor *pf;
    int thread;
};

/* Claims and runs iterations until none is left or one has failed. */
static void run_worker(struct parfor *pf, int thread)
{
    for (;;) {
        pthread_mutex_lock(&pf->mu);
        int i = pf->failed_i < pf->n ? pf->n : pf->next++;
        pthread_mutex_unlock(&pf->mu);
        if (i >= pf->n) return;
        int rc = pf->body(i, thread, pf->ctx);
        if (rc) {
            pthread_mutex_lock(&pf->mu);
            if (i < pf->failed_i) pf->failed_i = i, pf->rc = rc;
            pthread_mutex_unlock(&pf->mu);
        }
    }
}

static void *worker_main(void *arg)
{
    struct worker *w = arg;
    run_worker(w->pf, w->thread);
    return NULL;
}

int fit_parfor(int n, int threads, int (*body)(int i, int thread, void *ctx), void *ctx)
{
    struct parfor pf = {.next = 0, .n = n, .failed_i = n, .rc = 0, .body = body, .ctx = ctx};
    if (threads > FIT_THREADS_MAX) threads = FIT_THREADS_MAX;
    if (threads > n) threads = n;
    pthread_t tid[FIT_THREADS_MAX];
    struct worker w[FIT_THREADS_MAX];
    int started = 0;
    pthread_mutex_init(&pf.mu, NULL);
    for (int t = 1; t < threads; t++) {
        w[started] = (struct worker){&pf, t};
        if (pthread_create(&tid[started], NULL, worker_main, &w[started]) == 0) started++;
    }
    run_worker(&pf, 0);
    for (int t = 0; t < started; t++) pthread_join(tid[t], NULL);
    pthread_mutex_destroy(&pf.mu);
    return pf.rc;
}
