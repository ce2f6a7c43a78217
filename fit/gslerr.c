/* gslerr.c: fit/'s process policies (see gslerr.h): GSL's aborting default handler is turned off
 * once per process, a handler of the program's own is left in place; OpenBLAS runs each call on
 * the calling thread. */
#include "fit/gslerr.h"

#include <gsl/gsl_errno.h>
#include <pthread.h>
#include <stdlib.h>

/* The one piece of global state in fit/: GSL's handler is global itself. */
static pthread_once_t policy_once = PTHREAD_ONCE_INIT;

/* OpenBLAS's own (weak: another BLAS has none, and then nothing is set). */
void openblas_set_num_threads(int n) __attribute__((weak));

/* OpenBLAS's pthread build starts a pool of threads when it loads, sized by OPENBLAS_NUM_THREADS
 * or else by the cores, and the pool spins for work for about a tenth of a second before it
 * sleeps: 0.1 s of CPU in every `ips` command, 3x the reference fit's. Statically linked, this
 * constructor runs before OpenBLAS's (priority 101 sorts first in .init_array) and asks for one
 * thread, so no pool starts; a value the user set is kept. Linked to a shared OpenBLAS, whose
 * constructor runs first, it changes nothing, and fit_gsl_policy() still sets one thread. */
__attribute__((constructor(101))) static void blas_no_pool(void)
{
    setenv("OPENBLAS_NUM_THREADS", "1", 0);
}

static void policy_apply(void)
{
    /* GSL has no getter: swapping in the silent handler returns the one in place; NULL is GSL's
     * default (print and abort), anything else the program's own choice, which is restored */
    gsl_error_handler_t *previous = gsl_set_error_handler_off();
    if (previous) gsl_set_error_handler(previous);
    /* parallelism is ipsd's (fit workers, the sweep's r on threads): a BLAS call that split
     * itself over the cores would fight them */
    if (openblas_set_num_threads) openblas_set_num_threads(1);
}

void fit_gsl_policy(void)
{
    pthread_once(&policy_once, policy_apply);
}
