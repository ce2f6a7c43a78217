/* cmd_bench.c: `ips bench [--quick] [--json]`: figures, never pass/fail.
 * (a) Design-matrix accuracy against run time: on the reference scan positions (9 x 9 spots at
 *     0.6 um steps in a 6 um pixel) at r = 7, the fast design matrix (fit/design.h) at several
 *     quadrature settings against a reference built by adaptive quadrature (fit_box_integral at
 *     rel_tol 1e-14): the largest error relative to the largest entry of its row (the measure of
 *     fit_design_opts_for_tol), the largest relative error of an integrated entry, the median
 *     build time, and the cost in radial evaluations; also for extreme spots (R = 30, 0.05 um).
 * (b) The full job on the reference scan (bench_scan.h, generated from the reference file):
 *     sweep r = 1..8, F-test at r = 7 (top, left, bottom) and Wiener, min and median wall time
 *     over repeated runs on one core (this program is single-threaded), and the LM sweep.
 * (c) Process start-up: the wall time of starting (posix_spawn: vfork + exec) and reaping
 *     `ips box` (this executable), the reference job as a whole `ips fit` process (the scan
 *     written to a temporary file) and /bin/true, interleaved, median and min of many runs,
 *     measured first while this process is small; the difference is what a short `ips` command
 *     costs beyond the operating system's own price of a process (loading its libraries, mostly;
 *     target <= 3 ms). */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

#include "base/clock.h"
#include "bench_scan.h"
#include "cliutil.h"
#include "commands.h"
#include "fit/box.h"
#include "fit/design.h"
#include "fit/model.h"
#include "fit/wiener.h"
#include "instrument/scanfile.h"
#include "instrument/simperf.h"
#include "json/fitjson.h"

#define BENCH_R 7           /* the paper's r */
#define REF_TOL 1e-14       /* accuracy of the reference matrix */
#define MAX_RUNS 100000     /* cap on timed repetitions of one measurement */
#define STARTUP_RUNS 300    /* start-ups of each program (--quick: STARTUP_RUNS / 5) */

static const char usage[] =
    "usage: ips bench [--quick] [--json]\n"
    "  Design-matrix accuracy against run time, and the time of the full fit of the reference\n"
    "  scan (sweep r = 1..8, F-test, Wiener), the start-up cost of an ips process against\n"
    "  /bin/true, and the simulated bench's full paper scan with its leave-out rule.\n"
    "  --quick: fewer repetitions. --json: machine-readable output.\n";

/* Accuracy settings of the table: a target tolerance and the quadrature order it stands for;
 * the segment spans come from fit_design_opts_for_tol(tol). */
static const struct {
    double tol;
    int order;
} settings[] = {{1e-3, 6},   {1e-5, 8},   {1e-7, 10}, {1e-9, 12},
                {1e-11, 14}, {1e-13, 16}, {1e-15, 20}};
#define N_SETTINGS (sizeof settings / sizeof settings[0])

/* The spot positions of a table: the reference scan's; AROUND_N spots of a 15 x 15 raster at
 * 2.5 um steps around the pixel, 0.5-14.5 um beyond its edges (the raster of `--region all`, in
 * one batch: lines at equal distances share sweeps); or FAR_N spots around the pixel at 50-500
 * um in every direction (a small spot's jitter far from its pixel, POST /api/jitter: each line's
 * sweep starts at its nearest node, design.c). */
enum { SET_REF, SET_AROUND, SET_FAR, AROUND_N = 15 * 15 - 9, FAR_N = 16 };

/* Spot radii: the paper's, and two extremes at a few settings (indices into settings); then a
 * 0.0122 um spot (5 nm light) and a 0.05 um one far from the pixel. */
static const struct {
    double R;
    int first, step, set;
} radii[] = {{1.34, 0, 1, SET_REF},    {30.0, 1, 2, SET_REF},   {0.05, 1, 2, SET_REF},
             {1.34, 1, 2, SET_AROUND}, {0.0122, 1, 2, SET_FAR}, {0.05, 1, 2, SET_FAR}};

/* The positions of set (n of them) into x, y (room for the largest set's). */
static size_t spot_set(int set, double *x, double *y)
{
    const fit_scan_t *s = &bench_scan;
    if (set == SET_REF) {
        memcpy(x, s->x_um, sizeof(double) * s->n);
        memcpy(y, s->y_um, sizeof(double) * s->n);
        return s->n;
    }
    if (set == SET_AROUND) {
        size_t n = 0;
        for (int q = 0; q < 15 * 15; q++) {
            double xq = -14.5 + 2.5 * (q % 15), yq = -14.5 + 2.5 * (q / 15);
            if (xq >= 0 && xq <= s->pitch_um && yq >= 0 && yq <= s->pitch_um) continue;
            x[n] = xq, y[n++] = yq;
        }
        return n;
    }
    for (int k = 0; k < FAR_N; k++) { /* distances 50..500 um, angles 22.5 deg + 0.3 rad apart */
        double d = 50 + 450.0 * k / (FAR_N - 1), t = 0.3 + k * (M_PI / 8 + 0.3);
        x[k] = s->pitch_um / 2 + d * cos(t);
        y[k] = s->pitch_um / 2 + d * sin(t);
    }
    return FAR_N;
}

struct design_row {
    int set;
    double R, tol;
    fit_design_opts_t o;
    double row_err, entry_err, median_ms, ref_bound;
    double left_max;    /* the largest true value of an entry the leave-out rule left out */
    int runs, rows_out; /* rows_out: rows the leave-out rule left out whole (not in row_err) */
    fit_design_stats_t st;
};

struct job_times {
    int runs, lm_runs;
    double total_min, total_median, sweep, ftest, wiener, lm_sweep;
    int best_aic;
    double F, p_value;
};

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median of n values (reorders v). */
static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* The reference matrix for spot radius R at spots x, y (n) by adaptive quadrature; *bound gets
 * the largest error bound relative to its row's largest entry. */
static int reference_matrix(double R, const double *x, const double *y, size_t n, double *A,
                            double *bound, err_t *err)
{
    const fit_scan_t *s = &bench_scan;
    size_t m = BENCH_R * BENCH_R;
    double h = s->pitch_um / BENCH_R;
    *bound = 0;
    for (size_t k = 0; k < n; k++) {
        double row_max = 0, row_bound = 0;
        for (int j = 0; j < BENCH_R; j++)
            for (int i = 0; i < BENCH_R; i++) {
                fit_rect_t rect = {i * h, (i + 1) * h, j * h, (j + 1) * h};
                double v, b;
                int rc = fit_box_integral(R, &rect, x[k], y[k], REF_TOL, &v, &b, err);
                if (rc < 0 && rc != -ERANGE) return rc; /* -ERANGE: the bound says how good */
                A[k * m + (size_t)j * BENCH_R + i] = v;
                row_max = fmax(row_max, fabs(v));
                row_bound = fmax(row_bound, b);
            }
        *bound = fmax(*bound, row_bound / row_max);
    }
    return 0;
}

/* Errors of A against the reference: per row relative to the row's largest entry, and per
 * integrated (non-zero) entry. Entries the leave-out rule left out (0) are held to its bound, a
 * fraction of the spot's whole flux (design.h), not to the row's: their largest true value is
 * kept apart. */
static void matrix_errors(const double *A, const double *ref, size_t n, size_t m,
                          struct design_row *row)
{
    row->row_err = row->entry_err = row->left_max = 0;
    row->rows_out = 0;
    for (size_t k = 0; k < n; k++) {
        double row_max = 0, worst = 0;
        int kept = 0;
        for (size_t j = 0; j < m; j++) kept |= A[k * m + j] != 0;
        if (!kept) { /* every entry below skip_tol of the spot's flux: its bound is reported */
            row->rows_out++;
            for (size_t j = 0; j < m; j++) row->left_max = fmax(row->left_max, fabs(ref[k * m + j]));
            continue;
        }
        for (size_t j = 0; j < m; j++) {
            double e = fabs(A[k * m + j] - ref[k * m + j]);
            row_max = fmax(row_max, fabs(ref[k * m + j]));
            if (A[k * m + j] == 0) { /* left out */
                row->left_max = fmax(row->left_max, fabs(ref[k * m + j]));
                continue;
            }
            worst = fmax(worst, e);
            if (A[k * m + j] != 0 && ref[k * m + j] != 0)
                row->entry_err = fmax(row->entry_err, e / fabs(ref[k * m + j]));
        }
        row->row_err = fmax(row->row_err, worst / row_max);
    }
}

/* Builds the matrix for spots x, y (n) with row->o repeatedly (at least target_ms in all) and
 * measures it. */
static int time_design(const double *x, const double *y, size_t n, const double *ref,
                       double target_ms, double *A, double *times, struct design_row *row,
                       err_t *err)
{
    const fit_scan_t *s = &bench_scan;
    size_t m = BENCH_R * BENCH_R;
    double spent = 0;
    int runs = 0;
    while (runs < MAX_RUNS && (runs < 3 || spent < target_ms)) {
        double t = clock_mono_ms();
        int rc = fit_design_build(row->R, s->pitch_um, BENCH_R, x, y, n, &row->o, A, &row->st,
                                  err);
        if (rc) return rc;
        times[runs] = clock_mono_ms() - t;
        spent += times[runs++];
    }
    row->runs = runs;
    row->median_ms = median(times, runs);
    matrix_errors(A, ref, n, m, row);
    return 0;
}

/* Fills rows (room for N_SETTINGS per radius) and sets *n_rows. */
static int bench_design(int quick, struct design_row *rows, int *n_rows, err_t *err)
{
    size_t ns = bench_scan.n > AROUND_N ? bench_scan.n : AROUND_N, nm = ns * BENCH_R * BENCH_R;
    double *ref = malloc(sizeof(double) * nm), *A = malloc(sizeof(double) * nm);
    double *times = malloc(sizeof(double) * MAX_RUNS), *x = malloc(sizeof(double) * 2 * ns);
    double *y = x ? x + ns : NULL;
    int rc = 0;
    *n_rows = 0;
    if (!ref || !A || !times || !x) {
        rc = err_set(err, -ENOMEM, "out of memory");
        goto out;
    }
    for (size_t ri = 0; ri < sizeof radii / sizeof radii[0]; ri++) {
        double bound;
        size_t n = spot_set(radii[ri].set, x, y);
        if ((rc = reference_matrix(radii[ri].R, x, y, n, ref, &bound, err))) goto out;
        for (size_t si = (size_t)radii[ri].first; si < N_SETTINGS; si += (size_t)radii[ri].step) {
            struct design_row *row = &rows[(*n_rows)++];
            *row = (struct design_row){.set = radii[ri].set, .R = radii[ri].R,
                                       .tol = settings[si].tol, .ref_bound = bound};
            row->o = fit_design_opts_for_tol(settings[si].tol);
            row->o.order = settings[si].order;
            if ((rc = time_design(x, y, n, ref, quick ? 10 : 50, A, times, row, err))) goto out;
        }
    }
out:
    free(x);
    free(ref);
    free(A);
    free(times);
    return rc;
}

/* One full job on the reference scan; ms[0..2] = sweep, F-test, Wiener. */
static int job_once(fit_method_t method, int full, double ms[3], struct job_times *jt,
                    err_t *err)
{
    fit_options_t o = fit_options_default();
    o.method = method;
    o.design_tol = 1e-12;
    fit_sweep_t sw;
    fit_ftest_t ft;
    fit_wiener_t w;
    double t0 = clock_mono_ms();
    int rc = fit_sweep_run(&bench_scan, 1, 8, &o, &sw, err);
    if (rc) return rc;
    double t1 = clock_mono_ms();
    jt->best_aic = sw.best_aic;
    ms[0] = t1 - t0;
    if (!full) {
        fit_sweep_free(&sw);
        return 0;
    }
    /* as `ips fit --ftest` does: the sweep's linear r = 7 fit is H1 */
    const fit_result_t *h1 = &sw.fits[BENCH_R - 1];
    rc = method == FIT_LINEAR
             ? fit_ftest_with_h1(&bench_scan, h1, FIT_EDGE_TOP | FIT_EDGE_LEFT | FIT_EDGE_BOTTOM,
                                 &o, &ft, err)
             : fit_ftest_run(&bench_scan, BENCH_R, FIT_EDGE_TOP | FIT_EDGE_LEFT | FIT_EDGE_BOTTOM,
                             &o, &ft, err);
    fit_sweep_free(&sw);
    if (rc) return rc;
    double t2 = clock_mono_ms();
    jt->F = ft.F;
    jt->p_value = ft.p_value;
    if ((rc = fit_wiener_run(&bench_scan, 0, &w, err))) return rc;
    ms[2] = clock_mono_ms() - t2;
    ms[1] = t2 - t1;
    fit_wiener_free(&w);
    return 0;
}

static int bench_job(int quick, struct job_times *jt, err_t *err)
{
    int runs = quick ? 5 : 20, lm_runs = quick ? 1 : 3, rc = 0;
    double *t = malloc(sizeof(double) * 4 * (size_t)runs), ms[3];
    if (!t) return err_set(err, -ENOMEM, "out of memory");
    double *total = t, *sweep = t + runs, *ftest = t + 2 * runs, *wiener = t + 3 * runs;
    jt->runs = runs;
    jt->lm_runs = lm_runs;
    jt->total_min = INFINITY;
    for (int i = 0; i < runs; i++) {
        double t0 = clock_mono_ms();
        if ((rc = job_once(FIT_LINEAR, 1, ms, jt, err))) goto out;
        total[i] = clock_mono_ms() - t0;
        jt->total_min = fmin(jt->total_min, total[i]);
        sweep[i] = ms[0], ftest[i] = ms[1], wiener[i] = ms[2];
    }
    jt->total_median = median(total, runs);
    jt->sweep = median(sweep, runs);
    jt->ftest = median(ftest, runs);
    jt->wiener = median(wiener, runs);
    struct job_times lm = *jt;
    for (int i = 0; i < lm_runs; i++) {
        if ((rc = job_once(FIT_LM, 0, ms, &lm, err))) goto out;
        total[i] = ms[0];
    }
    jt->lm_sweep = median(total, lm_runs);
out:
    free(t);
    return rc;
}

/* ---- process start-up ---- */

struct startup {
    int runs;
    char box_cmd[64];
    double true_median, true_min, box_median, box_min, overhead;
    double fit_median, fit_min; /* the reference job as a whole `ips fit` process */
};

/* Wall time (ms) of starting argv[0] with argv (posix_spawn: vfork + exec, as hyperfine does),
 * and of its exit, its output discarded; -1 if it could not run or did not exit 0. */
static double spawn_ms(char *const argv[])
{
    posix_spawn_file_actions_t fa;
    if (posix_spawn_file_actions_init(&fa)) return -1;
    posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_adddup2(&fa, STDOUT_FILENO, STDERR_FILENO);
    double t0 = clock_mono_ms();
    pid_t pid;
    int rc = posix_spawn(&pid, argv[0], &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc) return -1;
    int status;
    while (waitpid(pid, &status, 0) < 0)
        if (errno != EINTR) return -1;
    double t = clock_mono_ms() - t0;
    return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? t : -1;
}

/* `ips box` (the paper's spot in the middle of a 6 um pixel) against /bin/true, interleaved so that
 * both see the same load. */
static int bench_startup(int quick, struct startup *su, err_t *err)
{
    char self[4096];
    ssize_t len = readlink("/proc/self/exe", self, sizeof self - 1);
    if (len <= 0) {
        int e = len < 0 ? errno : ENOENT;
        return err_set(err, -e, "cannot find this executable: %s", strerror(e));
    }
    self[len] = '\0';
    char *box[] = {self, "box", "1.34", "0", "6", "0", "6", "3", "3", NULL};
    char *tru[] = {access("/bin/true", X_OK) == 0 ? "/bin/true" : "/usr/bin/true", NULL};
    snprintf(su->box_cmd, sizeof su->box_cmd, "ips box 1.34 0 6 0 6 3 3");
    /* the reference job as `ips fit` runs it from a file: read, sweep 1..8, F-test, Wiener, the
     * JSON written (to /dev/null) */
    char scan_path[] = "/tmp/ips-bench-XXXXXX";
    int fd = mkstemp(scan_path);
    if (fd < 0) return err_set(err, -errno, "cannot make a temporary file: %s", strerror(errno));
    close(fd);
    int rc = scanfile_write(scan_path, &bench_scan, NULL, err);
    char *fit[] = {self, "fit", scan_path, "--ftest", "top,left,bottom", "--wiener", NULL};
    int runs = quick ? STARTUP_RUNS / 5 : STARTUP_RUNS;
    double *t = rc ? NULL : malloc(sizeof(double) * 3 * (size_t)runs);
    if (!t) {
        unlink(scan_path);
        return rc ? rc : err_set(err, -ENOMEM, "out of memory");
    }
    double *tt = t, *tb = t + runs, *tf = t + 2 * runs;
    spawn_ms(tru), spawn_ms(box), spawn_ms(fit); /* warm the page cache */
    for (int i = 0; i < runs; i++) {
        tt[i] = spawn_ms(tru);
        tb[i] = spawn_ms(box);
        tf[i] = spawn_ms(fit);
        if (tt[i] < 0 || tb[i] < 0 || tf[i] < 0) {
            const char *what = tt[i] < 0 ? tru[0] : tb[i] < 0 ? su->box_cmd : "ips fit";
            free(t);
            unlink(scan_path);
            return err_set(err, -EIO, "%s did not run", what);
        }
    }
    unlink(scan_path);
    su->fit_median = median(tf, runs);
    su->fit_min = tf[0];
    su->runs = runs;
    su->true_median = median(tt, runs);
    su->true_min = tt[0]; /* median sorted them */
    su->box_median = median(tb, runs);
    su->box_min = tb[0];
    su->overhead = su->box_median - su->true_median;
    free(t);
    return 0;
}

/* ---- output ---- */

/* Whether the measured row error meets the setting's tolerance, as far as the reference can
 * tell. */
static const char *tol_verdict(const struct design_row *r)
{
    if (r->left_max > r->st.max_skipped_bound) return "LEFT OUT ABOVE BOUND";
    if (r->row_err <= r->tol) return "ok";
    return r->row_err <= r->ref_bound ? "reference-limited" : "ABOVE TOL";
}

static void print_table(const struct design_row *rows, int n, const struct job_times *jt)
{
    printf("Design matrix of the reference scan positions (%zu spots, 9 x 9 at 0.6 um steps, "
           "pitch %g um), r = %d,\nagainst adaptive quadrature at rel_tol %g "
           "(errors relative to the row's largest entry, and per integrated entry)\n\n",
           bench_scan.n, bench_scan.pitch_um, BENCH_R, REF_TOL);
    printf("%7s %7s %5s %6s %5s  %10s %10s  %9s %6s  %12s %7s  %8s  %s\n", "R um", "tol",
           "order", "seg_dv", "seg_ds", "row err", "entry err", "median ms", "runs",
           "radial evals", "skipped", "ref bound", "row err vs tol");
    for (int i = 0; i < n; i++) {
        const struct design_row *r = &rows[i];
        if (r->set == SET_AROUND && (i == 0 || rows[i - 1].set != SET_AROUND))
            printf("Spots around the pixel: %d of a 15 x 15 raster at 2.5 um steps, 0.5-14.5 um "
                   "beyond its edges (the raster of --region all), r = %d:\n", AROUND_N, BENCH_R);
        if (r->set == SET_FAR && (i == 0 || rows[i - 1].set != SET_FAR))
            printf("Spots far from the pixel: %d at 50-500 um from its centre in all directions "
                   "(a small spot's jitter, POST /api/jitter), r = %d:\n", FAR_N, BENCH_R);
        printf("%7g %7.0e %5d %6g %5g  %10.2e %10.2e  %9.4f %6d  %12zu %7zu  %8.1e  %s", r->R,
               r->tol, r->o.order, r->o.seg_dv, r->o.seg_ds, r->row_err, r->entry_err,
               r->median_ms, r->runs, r->st.radial_evals, r->st.skipped, r->ref_bound,
               tol_verdict(r));
        if (r->st.skipped)
            printf(" (left out: at most %.1e um^2, bound %.1e; %d rows whole)", r->left_max,
                   r->st.max_skipped_bound, r->rows_out);
        printf("\n");
    }
    printf("(\"reference-limited\": the error is within the reference's own bound, so the\n"
           " comparison cannot resolve the setting's accuracy. Far from the pixel a cell is a\n"
           " second difference of nearly equal wedge integrals: what the sweeps' offsets and\n"
           " short segments near their origin leave grows with the distance, docs/numerics.md)\n");
    printf("\nFull job on the reference scan (%zu points): sweep r = 1..8 (linear, paper sigma, "
           "design tol 1e-12),\nF-test at r = %d (top,left,bottom), Wiener; %d runs, one core\n",
           bench_scan.n, BENCH_R, jt->runs);
    printf("  total   min %8.3f ms   median %8.3f ms   (target <= 20 ms)\n", jt->total_min,
           jt->total_median);
    printf("  sweep   median %8.3f ms\n  F-test  median %8.3f ms\n  Wiener  median %8.3f ms\n",
           jt->sweep, jt->ftest, jt->wiener);
    printf("  (best r by AIC %d; F = %.4f, p = %.3g)\n", jt->best_aic, jt->F, jt->p_value);
    printf("  LM sweep (method lm, same settings): median %.3f ms over %d run%s\n", jt->lm_sweep,
           jt->lm_runs, jt->lm_runs == 1 ? "" : "s");
}

static void print_startup(const struct startup *su)
{
    printf("\nProcess start-up (spawn, exec, exit; %d runs of each, interleaved)\n", su->runs);
    printf("  %-26s median %7.3f ms   min %7.3f ms\n", "/bin/true", su->true_median, su->true_min);
    printf("  %-26s median %7.3f ms   min %7.3f ms\n", su->box_cmd, su->box_median, su->box_min);
    printf("  ips box - /bin/true        median %7.3f ms   (target <= 3 ms)\n", su->overhead);
    printf("  ips fit, the reference job as a whole process (read, sweep r = 1..8, F-test,\n"
           "  Wiener, JSON out)           median %7.3f ms   min %7.3f ms   (target <= 10 ms)\n",
           su->fit_median, su->fit_min);
}

static json_t *startup_json(const struct startup *su)
{
    return json_pack("{s:i, s:s, s:{s:o, s:o}, s:{s:o, s:o}, s:o, s:{s:o, s:o}}", "runs",
                     su->runs, "command", su->box_cmd, "true_ms", "median",
                     fitjson_num(su->true_median), "min", fitjson_num(su->true_min),
                     "ips_box_ms", "median", fitjson_num(su->box_median), "min",
                     fitjson_num(su->box_min), "overhead_ms", fitjson_num(su->overhead),
                     "ips_fit_job_ms", "median", fitjson_num(su->fit_median), "min",
                     fitjson_num(su->fit_min));
}

static json_t *bench_json(const struct design_row *rows, int n, const struct job_times *jt)
{
    json_t *design = json_array();
    for (int i = 0; i < n; i++) {
        const struct design_row *r = &rows[i];
        json_array_append_new(
            design,
            json_pack("{s:o, s:i, s:o, s:i, s:o, s:o, s:o, s:o, s:o, s:o, s:i, s:I, s:I, s:o}",
                      "R_um", fitjson_num(r->R), "r", BENCH_R, "tol", fitjson_num(r->tol),
                      "order", r->o.order, "seg_dv", fitjson_num(r->o.seg_dv), "seg_ds",
                      fitjson_num(r->o.seg_ds), "skip_tol", fitjson_num(r->o.skip_tol),
                      "max_row_rel_err", fitjson_num(r->row_err), "max_entry_rel_err",
                      fitjson_num(r->entry_err), "median_ms", fitjson_num(r->median_ms),
                      "runs", r->runs, "radial_evals", (json_int_t)r->st.radial_evals,
                      "skipped", (json_int_t)r->st.skipped, "ref_bound",
                      fitjson_num(r->ref_bound)));
        json_object_set_new(json_array_get(design, (size_t)i), "spots",
                            json_string(r->set == SET_FAR      ? "far"
                                        : r->set == SET_AROUND ? "around"
                                                               : "reference"));
        json_object_set_new(json_array_get(design, (size_t)i), "rows_left_out",
                            json_integer(r->rows_out));
        json_object_set_new(json_array_get(design, (size_t)i), "left_out_max_um2",
                            fitjson_num(r->left_max));
        json_object_set_new(json_array_get(design, (size_t)i), "left_out_bound_um2",
                            fitjson_num(r->st.max_skipped_bound));
        json_object_set_new(json_array_get(design, (size_t)i), "verdict",
                            json_string(tol_verdict(r)));
    }
    json_t *job = json_pack(
        "{s:i, s:{s:o, s:o}, s:{s:o, s:o, s:o}, s:o, s:i, s:i, s:o, s:o}", "runs", jt->runs,
        "total_ms", "min", fitjson_num(jt->total_min), "median", fitjson_num(jt->total_median),
        "phases_median_ms", "sweep", fitjson_num(jt->sweep), "ftest", fitjson_num(jt->ftest),
        "wiener", fitjson_num(jt->wiener), "lm_sweep_ms", fitjson_num(jt->lm_sweep), "lm_runs",
        jt->lm_runs, "best_r_aic", jt->best_aic, "F", fitjson_num(jt->F), "p_value",
        fitjson_num(jt->p_value));
    return json_pack("{s:o, s:o}", "design", design, "job", job);
}

int cmd_bench(int argc, char **argv)
{
    int quick = 0, as_json = 0;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--quick") == 0) quick = 1;
        else if (strcmp(argv[i], "--json") == 0) as_json = 1;
        else if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            fputs(usage, stdout);
            return 0;
        } else
            return cli_fail(CLI_EXIT_USAGE, "bench", "unknown argument '%s' (see ips bench --help)",
                            argv[i]);
    }
    struct design_row rows[N_SETTINGS * sizeof radii / sizeof radii[0]];
    struct job_times jt = {0};
    struct startup su = {0};
    int n_rows, rc;
    err_t err;
    /* start-up first, while this process is small */
    if ((rc = bench_startup(quick, &su, &err)) || (rc = bench_design(quick, rows, &n_rows, &err)) ||
        (rc = bench_job(quick, &jt, &err)))
        return cli_fail(CLI_EXIT_FAILURE, "bench", "%s", err.msg);
    if (!as_json) {
        print_table(rows, n_rows, &jt);
        print_startup(&su);
    }
    fflush(stdout);
    simperf_t sp; /* the simulated bench: the paper's full scan and the leave-out rule */
    if (simperf_measure(quick, &sp, &err) != 0)
        return cli_fail(CLI_EXIT_FAILURE, "bench", "%s", err.msg);
    if (!as_json) {
        printf("\n");
        simperf_print(stdout, &sp);
        return 0;
    }
    json_t *root = bench_json(rows, n_rows, &jt);
    if (root) json_object_set_new(root, "startup", startup_json(&su));
    if (root) json_object_set_new(root, "simulator", simperf_json(&sp));
    rc = root ? fitjson_print(root, stdout) : -ENOMEM;
    json_decref(root);
    return rc ? cli_fail(CLI_EXIT_FAILURE, "bench", "writing the output failed") : 0;
}
