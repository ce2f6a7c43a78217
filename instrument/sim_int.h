/* sim_int.h (internal to instrument/): the simulated bench's state and how its files share it.
 * sim.h is the public face; the model is described there. One file per job:
 *   sim.c          configuration, open/close, the stage and the spot's position, the expected
 *                  image (photometry), the work counters
 *   sim_optics.c   the spot's radius: eq. 1 (via fit/airy.h), defocus, focus tolerance
 *   sim_leaveout.c the map's coarser levels and the leave-out rule's bounds
 *   sim_memo.c     the memo of pixel integrals and the integration of what it misses
 *   cam_sim.c      the simulated camera on top of all this (frames, exposure, gain, cam.h)
 * Nothing here calls the camera interface (cam.c, cam_sim.c): the camera sits on the bench, not
 * the other way round. */
#ifndef IPSD_INSTRUMENT_SIM_INT_H
#define IPSD_INSTRUMENT_SIM_INT_H

#include <stddef.h>
#include <stdint.h>

#include <gsl/gsl_rng.h>

#include "fit/design.h"
#include "instrument/sim.h"

#define SIM_LEFT_OUT (-1) /* an ask's level when the pixel is not integrated */
#define SIM_MAX_LEVELS 64

/* The map at a coarser resolution k (k divides m): block means P_k S, and the size of what that
 * leaves out, S - P_k S, in the two norms the bounds need. */
struct sim_level {
    int k;
    double *map;        /* k*k */
    double l1, max_dev; /* integral of |S - P_k S| (um^2), max |S - P_k S| */
};

struct sim_memo_entry {
    int64_t ku, kv;
    uint64_t kr;         /* bits of the radius */
    double value, bound; /* integral of S times the unit-peak Airy (um^2), and its left-out bound */
};

/* Open addressing on (relative position, radius); cap is a power of two. */
struct sim_memo {
    struct sim_memo_entry *e;
    unsigned char *used;
    size_t cap, n;
};

/* A memo miss of one capture: the relative position, the leave-out rule's choice, its memo slot. */
struct sim_ask {
    double u, v;
    int level; /* index into sim.lv, or SIM_LEFT_OUT */
    size_t slot;
};

struct sim {
    sim_config_t cfg;
    char scene_spec[512];
    scene_t *scene;
    const double *map;
    int m;
    scene_stats_t st;
    struct sim_level lv[SIM_MAX_LEVELS]; /* ascending k; the last is k = m (nothing left out) */
    int nlv;
    double R0, zR; /* in-focus radius and defocus depth (sim_optics.c) */
    fit_design_opts_t opts;
    gsl_rng *rng;
    stage_t *stage;
    double exposure_us, gain; /* the camera's settings (cam_sim.c); sim_expected scales by the
                                 exposure */
    double timeout_s;         /* the camera's frame timeout (cam_set_timeout), 0: default */
    cam_t *cam;               /* the handle sim_camera gives out (cam_sim.c), made once */
    void (*cam_release)(cam_t *cam); /* how sim_close releases it */
    struct sim_memo memo;
    struct sim_ask *asks; /* this capture's misses */
    size_t *pslot;        /* memo slot of each roi pixel */
    size_t *lvl_idx;      /* asks of one level */
    double *abuf, *ubuf, *vbuf;
    size_t ask_cap, n_asks;
    sim_stats_t stats;
};

/* sim_optics.c: sets s->R0 and s->zR from s->cfg (checked). */
void sim_optics_init(sim_t *s);

/* sim_leaveout.c: builds s->lv from s->map (every k dividing m; 0 or -ENOMEM), frees it. */
int sim_levels_build(sim_t *s);
void sim_levels_free(sim_t *s);

/* sim_leaveout.c: the leave-out rule of sim.h for a spot at (u, v) relative to the pixel
 * [0, p]^2, Airy scale a, whole-plane integral total, tolerance tol (same units as total): the
 * level to integrate with (SIM_LEFT_OUT or an index into s->lv) and in *bound the bound of what
 * that leaves out. */
int sim_leaveout_choose(const sim_t *s, double a, double total, double tol, double u, double v,
                        double *bound);

/* sim_memo.c: makes the memo (0 or -ENOMEM) and frees it with its work buffers. */
int sim_memo_init(sim_t *s);
void sim_memo_free(sim_t *s);

/* sim_memo.c: fills integ[] (S times the unit-peak Airy over each pixel of roi, um^2) and bnd[]
 * (the bound of what the leave-out rule left out of it) for a spot at sensor (xs, ys) of radius
 * R, from the memo or by integrating. roi lies inside the array (the caller checked it). 0,
 * -ENOMEM or a fit_design_build error. */
int sim_memo_integrate(sim_t *s, double xs, double ys, double R, const cam_roi_t *roi,
                       double *integ, double *bnd, err_t *err);

#endif
