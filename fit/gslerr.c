/* gslerr.c: fit/'s GSL error policy (see gslerr.h): GSL's aborting default handler is turned off
 * once per process, a handler of the program's own is left in place. */
#include "fit/gslerr.h"

#include <gsl/gsl_errno.h>
#include <pthread.h>

/* The one piece of global state in fit/: GSL's handler is global itself. */
static pthread_once_t policy_once = PTHREAD_ONCE_INIT;

static void policy_apply(void)
{
    /* GSL has no getter: swapping in the silent handler returns the one in place; NULL is GSL's
     * default (print and abort), anything else the program's own choice, which is restored */
    gsl_error_handler_t *previous = gsl_set_error_handler_off();
    if (previous) gsl_set_error_handler(previous);
}

void fit_gsl_policy(void)
{
    pthread_once(&policy_once, policy_apply);
}
