/* simperf.h: the simulated bench's figures for `ips bench` (never pass/fail): the wall time of the
 * paper's full scan (51 x 51 points, 12 frames of a 9 x 9 sub-frame each, paperlike scene, one
 * core) at several leave-out tolerances, what the leave-out rule saves, and the error it makes:
 * the largest difference of any pixel's expected signal, over the whole raster, from the run that
 * integrates everything (tolerance 0), next to the largest bound the simulator reported. */
#ifndef IPSD_INSTRUMENT_SIMPERF_H
#define IPSD_INSTRUMENT_SIMPERF_H

#include <stddef.h>
#include <stdio.h>

#include <jansson.h>

#include "base/err.h"

#define SIMPERF_MAX_ROWS 8

typedef struct simperf_row {
    double tol;                             /* leave-out tolerance (fraction of the spot's flux) */
    double scan_s;                          /* wall time of the raster (moves, captures, noise) */
    double integrate_s, noise_s;            /* of which integration, drawing frames */
    size_t full, coarse, uniform, left_out; /* integrations by kind (sim_stats_t) */
    double max_error_e, max_bound_e; /* vs tolerance 0: largest actual error, largest bound (e-) */
} simperf_row_t;

typedef struct simperf {
    size_t points, frames, pixel_frames; /* of one scan */
    double flux_e;                       /* the spot's flux per frame (e-) */
    double setup_s;                      /* centring, focus and exposure from a random start */
    int setup_evaluations;
    size_t n_rows;
    simperf_row_t rows[SIMPERF_MAX_ROWS]; /* rows[0]: tolerance 0 */
    int default_row;                      /* index of the simulator's default tolerance */
} simperf_t;

/* Measures the figures (about 15 s on one core; quick: tolerances 0 and the default only, about
 * 6 s). Returns 0 or a negative errno with err. */
int simperf_measure(int quick, simperf_t *out, err_t *err);

/* Prints the figures as a table. */
void simperf_print(FILE *f, const simperf_t *p);

/* The figures as a new JSON object (the caller's). */
json_t *simperf_json(const simperf_t *p);

/* simperf_measure then simperf_print to f. Returns 0 or a negative errno with err. */
int simperf_run(FILE *f, int quick, err_t *err);

#endif
