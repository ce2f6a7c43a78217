/* base/opts.c: the shared getopt_long loop and typed option values (see base/opts.h). */
#include "base/opts.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "base/parse.h"

const char *opts_name(const struct option *longopts, int val)
{
    for (const struct option *o = longopts; o->name; o++)
        if (o->val == val) return o->name;
    return "?";
}

/* The option getopt just rejected, as the user wrote it. */
static const char *rejected(int argc, char **argv)
{
    int i = optind - 1;
    return i >= 1 && i < argc ? argv[i] : "?";
}

int opts_parse(int argc, char **argv, const char *shortopts, const struct option *longopts,
               int help_val, const char *hint, opts_fn fn, void *user, int *first_pos, err_t *err)
{
    char spec[64];
    snprintf(spec, sizeof spec, ":%s", shortopts ? shortopts : "");
    opterr = 0;
    optind = 1;
    int c;
    while ((c = getopt_long(argc, argv, spec, longopts, NULL)) != -1) {
        if (help_val && c == help_val) return 1;
        if (c == ':') {
            if (optopt > 0 && optopt < 256 && strchr(shortopts ? shortopts : "", optopt))
                return err_set(err, -EINVAL, "-%c needs a value", optopt);
            return err_set(err, -EINVAL, "--%s needs a value", opts_name(longopts, optopt));
        }
        if (c == '?') {
            const char *a = rejected(argc, argv);
            /* getopt_long sets optopt to a flag's val when it was given a value: --flag=x */
            if (optopt >= 256 || (optopt && strncmp(a, "--", 2) == 0 && strchr(a, '=')))
                if (strcmp(opts_name(longopts, optopt), "?"))
                    return err_set(err, -EINVAL, "--%s takes no value", opts_name(longopts, optopt));
            return err_set(err, -EINVAL, "unknown option '%s' (see %s)", a, hint);
        }
        int rc = fn(c, optarg, user, err);
        if (rc) return rc;
    }
    *first_pos = optind;
    return 0;
}

int opts_int(const char *name, const char *text, long long lo, long long hi, long long *v,
             err_t *err)
{
    if (parse_ll(text, v) < 0)
        return err_set(err, -EINVAL, "--%s must be an integer (got '%s')", name, text);
    if (*v < lo || *v > hi)
        return err_set(err, -EINVAL, "--%s must be between %lld and %lld (got %lld)", name, lo, hi,
                       *v);
    return 0;
}

int opts_int32(const char *name, const char *text, int lo, int hi, int *v, err_t *err)
{
    long long x;
    int rc = opts_int(name, text, lo, hi, &x, err);
    if (rc == 0) *v = (int)x;
    return rc;
}

int opts_num(const char *name, const char *text, double lo, double hi, double *v, err_t *err)
{
    if (parse_double(text, v) < 0)
        return err_set(err, -EINVAL, "--%s must be a number (got '%s')", name, text);
    if (*v < lo || *v > hi)
        return err_set(err, -EINVAL, "--%s must be between %g and %g (got %s)", name, lo, hi, text);
    return 0;
}
