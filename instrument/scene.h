/* scene.h: what the simulated bench looks at: a sensor (array size, pitch, gain, read noise, bias,
 * ADC full scale, full well) and the sensitivity map that every one of its pixels shares.
 *
 * Coordinates (docs/contracts.md): pixel (col, row) spans [col p, (col+1) p] x [row p, (row+1) p]
 * sensor micrometres, x to the right, y downward (row 0 is the top edge). Inside a pixel the map
 * lives on [0, p]^2 with the same orientation.
 *
 * Representation: the map is piecewise constant on an m x m split of the pixel (row-major, y then
 * x: cell (i, j) at index j*m + i), so that the simulator's pixel integrals are exact for it.
 * Built-in scenes:
 *   uniform        m = 1, sensitivity 1 everywhere;
 *   FAMILY[:M]     a function of the position in the pixel averaged over each of M x M cells
 *                  (default 30, 0.2 um cells at 6 um pitch) by 8 x 8 Gauss-Legendre
 *                  (scene_family.c):
 *     paperlike    the pixel the paper finds (fill-factor dips of 25-30 % at the top, left and
 *                  bottom edges, none on the right, a few percent of smooth structure in the
 *                  middle; scene_paperlike_value);
 *     gradient     a linear tilt, +-10 % across x and +-5 % across y;
 *     dip          a central microlens dip, 15 % deep, sigma p/7;
 *     deadcorner   the top-right third x third of the pixel at 5 %;
 *     edge         a sharp step: the left 45 % of the pixel at 70 %;
 *     softedge     the same step as a logistic of width p/20;
 *     ring         a ring 20 % deep of radius 0.3 p and sigma p/20 about the centre;
 *     busline      a line 0.5 um wide at x = 0.6 p passing 40 %;
 *     diagedge     below the diagonal x + y = 0.9 p at 75 %;
 *     bowl         85 % at the centre rising quadratically to 115 % at the corners;
 *     twodips      two dips 20 % deep of sigma p/14 at (0.3, 0.35) p and (0.7, 0.65) p;
 *   map:FILE       a map read from a JSON file: {"S": [...], "r": m} or a bare array of m*m
 *                  numbers, any m in 1..256, values finite and >= 0.
 * The truth for an r x r fit (scene_truth) is the exact mean of this same representation over each
 * sub-pixel (area-weighted overlaps), so simulator and truth are consistent by construction. */
#ifndef IPSD_INSTRUMENT_SCENE_H
#define IPSD_INSTRUMENT_SCENE_H

#include <stddef.h>

#include "base/err.h"

#define SCENE_MAX_RES 256
#define SCENE_FAMILY_RES 30
#define SCENE_PAPERLIKE_RES SCENE_FAMILY_RES

typedef struct scene_sensor {
    int cols, rows;       /* array size, pixels */
    double pitch_um;      /* pixel pitch p */
    double gain_e_per_dn; /* G, at analogue gain 1 */
    double read_noise_e;  /* Gaussian read noise, electrons rms */
    double bias_dn;       /* ADC offset B */
    double full_scale_dn; /* ADC clip (14 bit: 16383) */
    double full_well_e;   /* photo-electrons a pixel holds before it clips */
} scene_sensor_t;

/* The paper's sensor (6 um, G = 3.153 e-/DN, 5.67 e-, B = 100 DN, 14 bit) as a 256 x 256 array. */
scene_sensor_t scene_sensor_default(void);

/* Checks a sensor description; returns 0 or -EINVAL naming the bad field. */
int scene_sensor_check(const scene_sensor_t *s, err_t *err);

typedef struct scene scene_t;

/* Summary figures of a map, used for the simulator's leave-out bounds. */
typedef struct scene_stats {
    double mean;    /* mean sensitivity over the pixel */
    double max;     /* largest cell value */
    double l1_dev;  /* integral over the pixel of |S - mean| (um^2) */
    double max_dev; /* largest |S - mean| */
} scene_stats_t;

/* Opens a scene from spec ("uniform", "paperlike", "paperlike:M", "map:FILE") on a copy of
 * sensor. *out is owned by the caller (scene_close). Returns 0, -EINVAL (bad spec, sensor or map
 * file content, named in err), -ENOENT (no map file) or -ENOMEM. */
int scene_open(const char *spec, const scene_sensor_t *sensor, scene_t **out, err_t *err);

/* Opens a scene from an explicit m x m map (copied). name is copied (may be NULL). */
int scene_open_map(const double *map, int m, const scene_sensor_t *sensor, const char *name,
                   scene_t **out, err_t *err);

void scene_close(scene_t *s);

/* Borrowed views, valid until scene_close. */
const scene_sensor_t *scene_sensor(const scene_t *s);
const char *scene_name(const scene_t *s);
const double *scene_map(const scene_t *s, int *m);
const scene_stats_t *scene_stats(const scene_t *s);

/* The true r x r map: the mean of the representation over each sub-pixel (row-major, y then x),
 * into caller-allocated S (r*r). r in 1..256. Returns 0 or -EINVAL / -ENOMEM. */
int scene_truth(const scene_t *s, int r, double *S, err_t *err);

/* The paperlike sensitivity at (x, y) um in a pixel of pitch p (the continuous function the
 * paperlike scene averages; x, y in [0, p]). */
double scene_paperlike_value(double x, double y, double p);

/* A family's continuous sensitivity S(x, y) in a pixel of pitch p. */
typedef double (*scene_fn)(double x, double y, double p);

/* The family named by the first len characters of name, NULL when there is none. */
scene_fn scene_family(const char *name, size_t len);

/* The name of family i (0, 1, ...), NULL past the last: for listings and benchmarks. */
const char *scene_family_name(size_t i);

#endif
