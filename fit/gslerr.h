/* gslerr.h: fit/'s policy for GSL's error handler, which is process-global, and for OpenBLAS's
 * threads (one per call: the parallelism is the callers', docs/numerics.md "Threads").
 *
 * GSL reports every failure twice: through the return code (or a NaN) of the call, and by
 * calling the error handler, whose default prints the reason and calls abort(). fit/ checks every
 * return code and turns failures into negative errnos with a message, so the handler's abort
 * would only kill a server over one bad integral. Every public fit/ function that can reach GSL
 * therefore calls fit_gsl_policy() first: once per process (pthread_once) it replaces GSL's default
 * handler by gsl_set_error_handler_off()'s silent one. A handler the program installed itself
 * before its first fit/ call is put back and kept (it must return for fit/ to report the error);
 * one installed later simply replaces ours. The other rooms that call GSL themselves (instrument/:
 * random numbers, quadrature tables, the focus parabola) call fit_gsl_policy() in their entry
 * points too, so no program of ipsd has to remember gsl_set_error_handler_off(). */
#ifndef IPSD_FIT_GSLERR_H
#define IPSD_FIT_GSLERR_H

void fit_gsl_policy(void);

#endif
