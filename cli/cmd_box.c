/* cmd_box.c: `ips box R X0 X1 Y0 Y1 XK YK [--tol T]`: the integral of the unit-peak Airy spot of
 * first-zero radius R centred at (XK, YK) over [X0,X1] x [Y0,Y1] (um, fit_box_integral), then its
 * error bound, printed with %.17g. Arguments are parsed by hand, not getopt: coordinates may be
 * negative and would look like options. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "base/parse.h"
#include "cliutil.h"
#include "commands.h"
#include "fit/box.h"

#define DEFAULT_TOL 1e-13

static const char usage[] =
    "usage: ips box R X0 X1 Y0 Y1 XK YK [--tol T]\n"
    "  Integral (um^2) of the unit-peak Airy spot of first-zero radius R (um) centred at\n"
    "  (XK, YK) over the box [X0,X1] x [Y0,Y1] (um), then a bound on its error, both %.17g.\n"
    "  --tol T   requested relative accuracy (default 1e-13; at least 1e-15)\n";

static const char *const names[] = {"R", "X0", "X1", "Y0", "Y1", "XK", "YK"};

/* Parses the options and the seven numbers; prints the problem and returns 2 on bad input. */
static int parse_args(int argc, char **argv, double v[7], double *tol)
{
    int n = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *tol_text = NULL;
        if (strcmp(a, "--tol") == 0) {
            if (i + 1 >= argc) return cli_fail(CLI_EXIT_USAGE, "box", "--tol needs a value");
            tol_text = argv[++i];
        } else if (strncmp(a, "--tol=", 6) == 0) {
            tol_text = a + 6;
        } else if (strncmp(a, "--", 2) == 0) {
            return cli_fail(CLI_EXIT_USAGE, "box", "unknown option '%s' (see ips box --help)", a);
        } else if (n == 7) {
            return cli_fail(CLI_EXIT_USAGE, "box", "too many arguments: '%s' after YK", a);
        } else if (parse_double(a, &v[n]) < 0) {
            return cli_fail(CLI_EXIT_USAGE, "box", "%s must be a finite number (got '%s')",
                            names[n], a);
        } else {
            n++;
        }
        if (tol_text && (parse_double(tol_text, tol) < 0 || !(*tol > 0 && *tol < 1)))
            return cli_fail(CLI_EXIT_USAGE, "box", "--tol must be a number in (0, 1) (got '%s')",
                            tol_text);
    }
    if (n < 7)
        return cli_fail(CLI_EXIT_USAGE, "box",
                        "expected 7 numbers R X0 X1 Y0 Y1 XK YK, got %d (see ips box --help)", n);
    return 0;
}

int cmd_box(int argc, char **argv)
{
    for (int i = 1; i < argc; i++)
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            fputs(usage, stdout);
            return 0;
        }
    double v[7], tol = DEFAULT_TOL, value, bound;
    int rc = parse_args(argc, argv, v, &tol);
    if (rc) return rc;
    fit_rect_t rect = {.x0 = v[1], .x1 = v[2], .y0 = v[3], .y1 = v[4]};
    err_t err;
    rc = fit_box_integral(v[0], &rect, v[5], v[6], tol, &value, &bound, &err);
    if (rc < 0 && rc != -ERANGE) return cli_fail(cli_exit_code(rc), "box", "%s", err.msg);
    printf("%.17g %.17g\n", value, bound);
    if (rc == -ERANGE) /* the value and its honest bound are printed, but not to tolerance */
        return cli_fail(CLI_EXIT_FAILURE, "box", "%s", err.msg);
    return 0;
}
