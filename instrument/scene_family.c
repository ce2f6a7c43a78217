/* scene_family.c: the built-in scene families of the simulated bench (scene.h), each a continuous
 * sensitivity S(x, y) over a pixel [0, p]^2 (y downward) that scene.c averages over M x M cells.
 * They span what a map must get right: the paper's pixel, smooth structure (a tilt, a central
 * microlens dip) and sharp structure (a dead corner, a step edge, a soft edge), so that choices
 * like the recommended r are measured on more than one kind of pixel. Five more (a ring, a bus
 * line 0.5 um wide, a diagonal edge, a bowl, two small dips) lie on no r x r grid of the sweep
 * and test choices beyond the families they were tuned on. */
#include "instrument/scene.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

/* Smooth edge dip of depth `depth` at distance d (um) from an edge, Gaussian of 1/e width w. */
static double edge_dip(double depth, double d, double w)
{
    return 1.0 - depth * exp(-(d * d) / (w * w));
}

double scene_paperlike_value(double x, double y, double p)
{
    /* Fill-factor dips at three edges (the paper's figs. 10-11: top, left, bottom; none on the
     * right), 1/e width p/10 (0.6 um at 6 um pitch), depths 28 %, 30 %, 25 %. */
    double w = 0.1 * p;
    double edges = edge_dip(0.28, y, w) * edge_dip(0.30, x, w) * edge_dip(0.25, p - y, w);
    /* A few percent of smooth structure in the middle (microlens imperfections, say): two
     * low-order waves and one bump, all fixed. */
    double t = x / p, s = y / p;
    double dt = t - 0.62, ds = s - 0.40;
    double centre = 1.0 + 0.03 * sin(2 * M_PI * t + 0.7) * sin(M_PI * s) +
                    0.025 * cos(2 * M_PI * s - 0.4) * sin(M_PI * t) +
                    0.02 * exp(-(dt * dt + ds * ds) / (2 * 0.12 * 0.12));
    return edges * centre;
}

/* A linear tilt: +-10 % across x, +-5 % across y (a pixel seen slightly off-normal). */
static double gradient_value(double x, double y, double p)
{
    return 1.0 + 0.2 * (x / p - 0.5) + 0.1 * (y / p - 0.5);
}

/* A central microlens dip: 15 % deep, Gaussian of sigma p / 7 (0.86 um at 6 um pitch), slightly
 * off centre. */
static double dip_value(double x, double y, double p)
{
    double dx = x / p - 0.53, dy = y / p - 0.47, s = 1.0 / 7;
    return 1.0 - 0.15 * exp(-(dx * dx + dy * dy) / (2 * s * s));
}

/* A dead corner: the top-right third x third of the pixel at 5 % (a contact, a defect). */
static double deadcorner_value(double x, double y, double p)
{
    return x > 2 * p / 3 && y < p / 3 ? 0.05 : 1.0;
}

/* A sharp step: the left 45 % of the pixel at 70 % (a metal line shading part of it). */
static double edge_value(double x, double y, double p)
{
    (void)y;
    return x < 0.45 * p ? 0.7 : 1.0;
}

/* The same step made soft: a logistic of width p / 20 (0.3 um) instead of a jump. */
static double softedge_value(double x, double y, double p)
{
    (void)y;
    return 1.0 - 0.3 / (1.0 + exp((x - 0.45 * p) / (0.05 * p)));
}

/* A ring: 20 % deep, radius 0.3 p about the centre, Gaussian cross-section of sigma p / 20 (the
 * rim of a microlens, say). */
static double ring_value(double x, double y, double p)
{
    double dx = x / p - 0.5, dy = y / p - 0.5, d = sqrt(dx * dx + dy * dy) - 0.3, s = 0.05;
    return 1.0 - 0.2 * exp(-(d * d) / (2 * s * s));
}

/* A bus line: a metal line 0.5 um wide (whatever the pitch) down the pixel at 0.6 p, passing
 * 40 %. */
static double busline_value(double x, double y, double p)
{
    (void)y;
    double x0 = 0.6 * p;
    return x >= x0 && x < x0 + 0.5 ? 0.4 : 1.0;
}

/* A diagonal step: below the line x + y = 0.9 p at 75 %. */
static double diagedge_value(double x, double y, double p)
{
    return x + y < 0.9 * p ? 0.75 : 1.0;
}

/* A bowl: 85 % at the centre rising quadratically to 115 % at the corners. */
static double bowl_value(double x, double y, double p)
{
    double dx = x / p - 0.5, dy = y / p - 0.5;
    return 0.85 + 0.6 * (dx * dx + dy * dy);
}

/* Two small dips: 20 % deep, Gaussian of sigma p / 14, at (0.3, 0.35) p and (0.7, 0.65) p. */
static double twodips_value(double x, double y, double p)
{
    double s = 1.0 / 14, ax = x / p - 0.3, ay = y / p - 0.35, bx = x / p - 0.7, by = y / p - 0.65;
    return 1.0 - 0.2 * exp(-(ax * ax + ay * ay) / (2 * s * s)) -
           0.2 * exp(-(bx * bx + by * by) / (2 * s * s));
}

static const struct family {
    const char *name;
    scene_fn fn;
} families[] = {
    {"paperlike", scene_paperlike_value}, {"gradient", gradient_value},
    {"dip", dip_value},                   {"deadcorner", deadcorner_value},
    {"edge", edge_value},                 {"softedge", softedge_value},
    {"ring", ring_value},                 {"busline", busline_value},
    {"diagedge", diagedge_value},         {"bowl", bowl_value},
    {"twodips", twodips_value},
};

#define N_FAMILIES (sizeof families / sizeof families[0])

scene_fn scene_family(const char *name, size_t len)
{
    for (size_t i = 0; i < N_FAMILIES; i++)
        if (strlen(families[i].name) == len && strncmp(families[i].name, name, len) == 0)
            return families[i].fn;
    return NULL;
}

const char *scene_family_name(size_t i)
{
    return i < N_FAMILIES ? families[i].name : NULL;
}
