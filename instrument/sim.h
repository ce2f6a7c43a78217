/* sim.h: the simulated optical bench: a scene (scene.h) under a diffraction-limited spot on a
 * simulated stage (stage.h), seen through a simulated camera (cam.h, backend "sim").
 *
 * Optics. The spot is the Airy pattern of eq. 2 with first-zero radius R0 = 1.22 lambda / (2 NA)
 * (eq. 1; 1.342 um for the paper's 550 nm and NA 0.25), or R0 given directly. Defocus keeps the
 * Airy shape and widens it: R(z) = R0 sqrt(1 + ((z - z_focus) / zR)^2), with the depth
 * zR = lambda / (2 NA^2) (the quarter-wave depth of focus, 4.4 um for the paper's optics) unless
 * set; the whole flux is the same at every z. sim_focus_tolerance() is the |z - z_focus| at which
 * R has grown by 1 %: zR sqrt(1.01^2 - 1) (0.62 um for the paper's optics).
 *
 * Geometry. Sensor micrometres as scene.h; the spot centre sits at stage (x, y) + mount offset
 * (plus the stage's positioning error and drift, stage.h), and its radius follows the stage z.
 *
 * Photometry. flux_e is the number of photo-electrons the whole spot would deliver in one frame to
 * a sensor of uniform sensitivity 1 at the reference exposure; it scales linearly with exposure.
 * A pixel's expected charge is flux_e (t / t_ref) * integral over the pixel of S(x, y) times the
 * unit-peak Airy, divided by the Airy's whole-plane integral 4 pi / a^2. The default 21500 e- puts
 * ~2e4 e- in the pixel when the spot sits in its middle, as the paper reports.
 *
 * A frame: every pixel's charge is drawn from Poisson(expected), clipped at the full well, plus
 * Gaussian read noise (electrons); DN = bias + charge * gain / G, rounded to an integer and clipped
 * to [0, full scale]. noiseless skips the Poisson and read noise (the rounding stays; the frame's
 * expected_dn holds the exact value). Random numbers: GSL mt19937 with the configured seed;
 * gsl_ran_poisson and the ziggurat Gaussian.
 *
 * Integration and the leave-out rule. Every pixel shares the scene's m x m piecewise-constant map,
 * so a pixel's signal is the dot product of one design row (fit/design.h: the Airy integrated over
 * each cell) with the map. The map is also kept at every coarser resolution k dividing m (block
 * means P_k S; k = 1 is the mean). Per pixel and spot position the simulator bounds rigorously,
 * with d the distance from the spot centre to the pixel, env the Airy envelope (airy.h) and
 * out(d) the flux outside the disc of radius d (encircled energy, fit_radial):
 *   whole pixel   <= max S * min(pixel area * env(d), out(d))
 *   k x k instead of the map  <= min(integral |S - P_k S| * env(d), max |S - P_k S| * out(d))
 * (the Airy is below env(d) on the whole pixel, and the pixel lies outside the disc). With tol =
 * leave_out_tol times the spot's whole flux: a pixel whose whole bound is below tol is not
 * integrated (noise and bias only); otherwise it is integrated with the coarsest k whose bound is
 * below tol (k = 1: one box integral), and with the full map when none is. The frame reports the
 * largest bound left out of any of its pixels (cam_frame_t.left_out_dn); sim_stats_t counts the
 * choices. leave_out_tol = 0 integrates every pixel with the full map.
 * Because a pixel's signal depends only on the spot's position relative to that pixel, results are
 * memoised by relative position (rounded to 1e-9 um, and evaluated at the rounded position) and
 * radius: a raster on a lattice commensurate with the pitch, as the paper's, integrates each
 * relative position once. */
#ifndef IPSD_INSTRUMENT_SIM_H
#define IPSD_INSTRUMENT_SIM_H

#include <stddef.h>

#include "instrument/cam.h"
#include "base/err.h"
#include "instrument/scene.h"
#include "instrument/stage.h"

typedef struct sim sim_t;

typedef struct sim_config {
    const char *scene;             /* scene spec (scene.h); NULL: "paperlike". Copied at open. */
    scene_sensor_t sensor;         /* scene_sensor_default() */
    double wavelength_um;          /* 0.55 */
    double na;                     /* 0.25 */
    double radius_um;              /* > 0: R0 directly; 0: from wavelength and NA by eq. 1 */
    double z_focus_um;             /* stage z of best focus (0) */
    double depth_um;               /* zR of the defocus model; 0: lambda / (2 NA^2) */
    double mount_x_um, mount_y_um; /* sensor position of the spot at stage x = y = 0 (0, 0) */
    double flux_e;            /* whole-spot photo-electrons per frame at ref exposure (21500) */
    double flat_e;            /* a uniform flat field on top of the spot (the photon-transfer
                                 lamp): photo-electrons per pixel per frame at the reference
                                 exposure, scaling with exposure as the spot does (0: none);
                                 switched with sim_set_flat */
    double ref_exposure_us;   /* reference exposure (10000 us) */
    double readout_s;         /* bench time per frame besides the exposure (0.02 s) */
    int noiseless;            /* no photon or read noise (0) */
    double leave_out_tol;     /* fraction of the spot's whole flux (1e-4); 0 integrates all */
    double design_tol;        /* accuracy of the pixel integrals relative to the largest cell
                                 (fit_design_opts_for_tol), 1e-7 */
    double temperature_c;     /* sensor temperature the frames report (25) */
    unsigned long seed;       /* noise of the frames (1) */
    stage_sim_config_t stage; /* stage_sim_config_default() */
    /* The camera's fault switch (tests; NULL: none): asked before each frame with the number of
     * frames this camera captured so far; answers SIM_FRAME_OK, SIM_FRAME_HANG (the camera stops
     * answering: the capture waits the camera's timeout, cam_set_timeout, then fails with
     * -ETIMEDOUT) or SIM_FRAME_FAIL (the capture fails at once with -EIO). */
    int (*frame_fault)(void *ctx, unsigned long long frame);
    void *frame_fault_ctx;
} sim_config_t;

enum { SIM_FRAME_OK, SIM_FRAME_HANG, SIM_FRAME_FAIL };

sim_config_t sim_config_default(void);

/* The most pixels one capture of the bench may ask for: its memo of pixel integrals
 * (sim_memo.c, 2^20 entries) kept below 70 % full; a larger region fails the capture with
 * "out of memory for the pixel memo". 856 x 856 is the largest square (a photon-transfer
 * region: srv_ptc.h). */
#define SIM_CAPTURE_PX_MAX 734003

/* Opens a bench. *out is the caller's (sim_close). Returns 0, -EINVAL (bad configuration, named
 * in err), -ENOENT (map file missing) or -ENOMEM. */
int sim_open(const sim_config_t *cfg, sim_t **out, err_t *err);

/* Closes the bench and its camera and stage handles; accepts NULL. */
void sim_close(sim_t *sim);

/* The bench's camera and stage: borrowed, valid until sim_close; do not close them. The camera
 * handle is made at the first sim_camera call (cam_sim.c), which returns NULL only when that
 * small allocation fails. */
cam_t *sim_camera(sim_t *sim);

/* Restarts the frames' noise from seed, as sim_open does with the configured one: what follows
 * is the same noise whenever the same seed is set before the same captures (an adaptive scan's
 * points are taken so, each from its own seed, so that a resumed scan reads the same values). */
void sim_reseed(sim_t *sim, unsigned long seed);
stage_t *sim_stage(sim_t *sim);

/* The bench behind a "sim" camera (from cam_open("sim", ...) or sim_camera), NULL for any other
 * camera. Borrowed. */
sim_t *sim_of_camera(cam_t *cam);

/* Borrowed view of the scene. */
const scene_t *sim_scene(const sim_t *sim);

/* R(z): the spot's first-zero radius at stage z (um). */
double sim_spot_radius(const sim_t *sim, double z_um);

/* R0, the in-focus radius, and the focus tolerance (1 % widening), both um. */
double sim_spot_radius0(const sim_t *sim);
double sim_focus_tolerance(const sim_t *sim);

/* Where the spot really is now: sensor x, y and stage z (um). */
void sim_spot(sim_t *sim, double *x_um, double *y_um, double *z_um);

/* The stage position (x, y) that puts the spot centre on the middle of pixel (col, row), ignoring
 * stage errors and drift; z is set to the focus. */
stage_pos_t sim_pixel_centre(const sim_t *sim, int col, int row);

/* Expected photo-electrons (noiseless) of the pixels of roi for a spot centred at sensor (xs, ys)
 * with radius R_um, at the current exposure: e_out (roi width * height, caller-allocated).
 * *left_out_e (may be NULL): the largest bound of the electrons left out of any pixel.
 * Returns 0, -EINVAL (bad roi or radius) or -ENOMEM. */
int sim_expected(sim_t *sim, double xs, double ys, double R_um, const cam_roi_t *roi, double *e_out,
                 double *left_out_e, err_t *err);

/* What the camera does (cam.h semantics; the simulated camera of cam_sim.c). */
int sim_info(sim_t *sim, cam_info_t *info);
int sim_set_exposure(sim_t *sim, double exposure_us, err_t *err);
int sim_set_gain(sim_t *sim, double gain, err_t *err);
int sim_capture(sim_t *sim, const cam_roi_t *roi, cam_frame_t *frame, err_t *err);

/* The flat-field lamp (sim_config_t.flat_e): e- per pixel per frame at the reference exposure; 0
 * switches it off (darks). Returns 0 or -EINVAL (negative or not finite). */
int sim_set_flat(sim_t *sim, double flat_e, err_t *err);

/* Work counters since opening (or since sim_reset_stats). */
typedef struct sim_stats {
    size_t frames;                          /* frames captured */
    size_t pixel_frames;                    /* pixels drawn, over all frames */
    size_t lookups;                         /* pixel expectations asked for */
    size_t hits;                            /* answered from the memo */
    size_t full, coarse, uniform, left_out; /* memo misses by what the leave-out rule chose:
                               the m x m map, a coarser k x k one, the mean, nothing */
    double max_left_out_e;       /* largest bound left out of any pixel of any frame (electrons) */
    double integrate_s, noise_s; /* CPU seconds in integration and in drawing frames */
} sim_stats_t;

void sim_get_stats(const sim_t *sim, sim_stats_t *stats);
void sim_reset_stats(sim_t *sim);

#endif
