/* base/opts.h: the command-line conventions of every ipsd program (ips and its commands, ipsd),
 * over getopt_long: one loop that names what is wrong in one line (a missing value, a value given
 * to a flag, an unknown option) and typed values that name their option and range. */
#ifndef IPSD_BASE_OPTS_H
#define IPSD_BASE_OPTS_H

#include <getopt.h>

#include "base/err.h"

/* Called for every option seen: val is the option's getopt value, arg its value (NULL for a
 * flag). Returns 0 or a negative errno with err. */
typedef int (*opts_fn)(int val, const char *arg, void *user, err_t *err);

/* Parses argv (argv[0] is the program or the command) with getopt_long over longopts and
 * shortopts (without the leading ':'; "" for none). help_val is the val of --help (0: none).
 * hint completes the unknown-option message: "unknown option '--x' (see HINT)".
 * Returns 0 with *first_pos the index of the first positional argument (the caller checks
 * them), 1 when --help was given (nothing else parsed after it), or a negative errno with err:
 * "--NAME needs a value", "--NAME takes no value", "unknown option '...' (see HINT)", or fn's
 * error. Options long_opts entries must have flag NULL and distinct val. */
int opts_parse(int argc, char **argv, const char *shortopts, const struct option *longopts,
               int help_val, const char *hint, opts_fn fn, void *user, int *first_pos, err_t *err);

/* The long name of option val ("?" when none): for messages. */
const char *opts_name(const struct option *longopts, int val);

/* An integer option in lo..hi: "--NAME must be an integer (got 'x')", "--NAME must be between LO
 * and HI (got V)". Returns 0 or -EINVAL with err. */
int opts_int(const char *name, const char *text, long long lo, long long hi, long long *v,
             err_t *err);
int opts_int32(const char *name, const char *text, int lo, int hi, int *v, err_t *err);

/* A finite number option in [lo, hi]: "--NAME must be a number (got 'x')", "--NAME must be
 * between LO and HI (got x)". Returns 0 or -EINVAL with err. */
int opts_num(const char *name, const char *text, double lo, double hi, double *v, err_t *err);

#endif
