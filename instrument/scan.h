/* scan.h: the scan procedure of the paper (section II.B) over any camera and stage (cam.h,
 * stage.h): centre the spot on the pixel of interest (POI), focus, choose the exposure, raster
 * the spot over n x n pixels around the POI capturing an m x m sub-frame k times per point, and
 * extract any pixel's response as a scan file for the fit.
 *
 * Coordinates. Stage micrometres; the POI's centre is where the setup put the spot
 * (scan_setup_t.centre). Pixel (dcol, drow) of the sub-frame, relative to the POI, spans
 * [cx - p/2 + dcol p, cx + p/2 + dcol p] x [cy - p/2 + drow p, ...] with y downward; extracted
 * positions are relative to that pixel's own top-left corner (docs/contracts.md), from the stage's
 * reported positions.
 *
 * Setup (scan_prepare), each step optional:
 *   exposure (rough): shorten until nothing saturates, lengthen when the spot is barely seen;
 *   centre: if a neighbour is brighter than the POI, step a pitch towards the POI; then balance
 *     the neighbours' counts: g_x = (right - left) / (right + left) over the 3 x 3 around the POI
 *     (columns of three), g_y = (bottom - top) / (bottom + top). Per axis, step by
 *     centre_step_um until g changes sign, narrow that bracket by false position (Illinois)
 *     down to centre_tol_um, then fit a line to g at 7 points over +-0.3 um around the bracket's
 *     root with 4 x setup_frames each: its zero is the centre (the fit averages the noise);
 *   focus: minimise the fraction of the 3 x 3's light on the 8 neighbours: a coarse sweep over
 *     +-focus_range_um in focus_step_um, then parabolas fitted to focus_points points over
 *     +-focus_window_um around the current best, re-centred until the vertex moves less than
 *     focus_tol_um (the metric is even about the focus, so a window centred on it has its vertex
 *     there); then centre again;
 *   exposure (final): scale so that the brightest pixel of the centred, focused spot sits at
 *     exposure_fill of the way from bias to saturation_dn (default 0.4: ~2e4 e- in the paper's
 *     sensor, as the paper has), leaving headroom for brighter points and noise; checked once.
 * Raster (scan_raster_run): points on a square lattice of step step_um, nx = area_px p / step + 1
 * per axis (51 for 5 x 5 pixels of 6 um in 0.6 um steps) centred on the POI centre, row by row from
 * the top-left corner (index i: column i % nx, row i / nx). Positions depend only on the config and
 * the setup, so a raster can start at any index (resume after the last stored point).
 * Every captured point goes to hooks->point (the server stores it) and, when given, into a
 * scan_raster_t. The stop flag is read between points and between setup evaluations.
 *
 * Files: scan_config.c (defaults and checks, from scan_limits.h: a scan's defaults and limits are
 * defined there once), scan_setup.c (exposure, centring, focus), scan_raster.c (the raster and
 * scan_raster_t), scan_extract.c (scan files: a pixel of a raster, the direct grid),
 * scan_points.c (the POI at given positions, batch after batch: an adaptive scan), and
 * scan_capture.c (frames at a position, hooks; scan_int.h). */
#ifndef IPSD_INSTRUMENT_SCAN_H
#define IPSD_INSTRUMENT_SCAN_H

#include "fit/scandata.h" /* fit_scan_t */

#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "instrument/cam.h"
#include "base/err.h"
#include "instrument/stage.h"

/* scanfile.h's scanfile_t (declared there; not included here, as scanfile.h includes this). */
struct scanfile;

typedef struct scan_config {
    int poi_col, poi_row;    /* pixel of interest, sensor column and row */
    stage_pos_t start;       /* stage position near the POI's centre; z: the focus guess */
    int area_px;             /* n: raster over n x n pixels (5) */
    double step_um;          /* raster step (0.6) */
    int subframe_px;         /* m: odd sub-frame side captured per point (9) */
    int frames;              /* k: frames per raster point (12) */
    int setup_frames;        /* frames per evaluation while centring and focusing (4) */
    double saturation_dn;    /* no pixel may reach this (16000) */
    double exposure_fill;    /* brightest pixel's target, fraction of bias..saturation (0.4) */
    double exposure_us;      /* starting exposure (10000) */
    double gain;             /* analogue gain (1) */
    int do_centre;           /* setup steps to run (1, 1, 1); with none the centre is start */
    int do_focus;
    int do_exposure;
    double centre_step_um;   /* step while looking for the balance's sign change (0.5) */
    double centre_tol_um;    /* bracket width that hands over to the line fit (0.05) */
    int centre_max_iter;     /* evaluations of the bracketing stage at most (40) */
    double focus_range_um;   /* coarse sweep +- this around start.z (15) */
    double focus_step_um;    /* coarse sweep step (2.5) */
    double focus_window_um;  /* parabola window half-width (3) */
    int focus_points;        /* points per parabola (9) */
    double focus_tol_um;     /* refinement stops when the vertex moves less (0.05) */
    int keep_frames;         /* keep every raw frame in the raster (0) */
    int use_expected;        /* average the camera's expected_dn when it has one: a noiseless
                                simulation without ADC rounding (0) */
    /* sensor constants written into extracted scan files; NaN: the camera's own (cam_info_t) */
    double pitch_um, bias_dn, gain_e_per_dn, read_noise_e, full_scale_dn;
    double spot_radius_um;   /* R of eq. 1 for the scan file; must be set (NaN: error) */
} scan_config_t;

/* The defaults above (the scan's own from scan_limits.h); the caller fills in the POI, the start
 * and the spot radius. */
scan_config_t scan_config_default(void);

/* Checks cfg: each field in its range (scan_limits.h), frames x subframe_px^2 samples a point,
 * and against the camera (info may be NULL to skip those checks): the sub-frame on the sensor.
 * The raster's whole steps need the pitch: scan_raster_init checks them. Returns 0 or -EINVAL
 * naming the field. */
int scan_config_check(const scan_config_t *cfg, const cam_info_t *info, err_t *err);

/* Raster points per axis (nx) for cfg: scan_axis_points (scan_limits.h) of cfg's area and step.
 * pitch_um: the sensor pitch to use. */
int scan_points_per_axis(const scan_config_t *cfg, double pitch_um);

/* What the setup found and the sensor constants it settled (cfg's, or the camera's where cfg
 * has NaN). A resumed raster needs the same setup: store it with the scan. */
typedef struct scan_setup {
    stage_pos_t centre; /* stage position of the spot centred on the POI, in focus */
    double exposure_us, gain;
    double pitch_um, bias_dn, gain_e_per_dn, read_noise_e, full_scale_dn, spot_radius_um;
    double imbalance_x, imbalance_y; /* g_x, g_y at the centre */
    double neighbour_fraction;       /* focus metric at the centre */
    double peak_dn; /* brightest mean pixel (bias included) at the chosen exposure */
    int centre_iterations, focus_evaluations;
} scan_setup_t;

/* One captured raster point, as handed to hooks->point. All pointers are borrowed for the call. */
typedef struct scan_point {
    size_t index, count; /* this point of count */
    int ix, iy;          /* column, row of the raster */
    stage_pos_t commanded, reported;
    double exposure_us, gain;
    int64_t timestamp_ns;      /* of the first frame */
    int frames, width, height; /* k, and the sub-frame (m x m) */
    const double *mean_dn;     /* width*height means of the k frames (bias included) */
    const double *var_dn;      /* their sample variances (NaN for k = 1) */
    const uint16_t *raw;       /* k*width*height frames, frame after frame; NULL unless
                                  keep_frames */
    const int64_t *frame_timestamps_ns; /* k: each frame's start of exposure (timestamp_ns) */
    const uint64_t *camera_frame_ids;   /* k: the camera's own frame ids (0 where it has none) */
    double left_out_dn;        /* the simulator's bound on what it left out; 0 otherwise */
} scan_point_t;

typedef struct scan_hooks {
    /* each raster point as captured (already in the scan_raster_t, when one is given); a
       non-zero return stops the raster after this point (-ECANCELED) */
    int (*point)(const scan_point_t *pt, void *user);
    /* progress: phase "exposure", "centre", "focus" or "raster", done of total (total 0 when
       unknown) */
    void (*progress)(const char *phase, size_t done, size_t total, void *user);
    void *user;
    const atomic_int *stop; /* non-zero: stop at the next check (-ECANCELED) */
} scan_hooks_t;

/* A raster in memory: every point's reported position and sub-frame means. Owned arrays; release
 * with scan_raster_free. */
typedef struct scan_raster {
    scan_config_t cfg;
    scan_setup_t setup;
    int nx;                   /* points per axis */
    size_t count, captured;   /* nx * nx, and how many are in */
    int m;                    /* sub-frame side */
    stage_pos_t *pos;         /* count reported positions */
    double *mean_dn, *var_dn; /* count * m * m */
    uint16_t *raw;            /* count * frames * m * m when keep_frames, else NULL */
    unsigned char *have;      /* count flags: point captured */
} scan_raster_t;

/* Settles the sensor constants and runs the setup steps of cfg (none: the centre is cfg->start
 * and the exposure cfg->exposure_us). *setup gets what was found (on error: the state so far).
 * Returns 0, -ECANCELED (stopped), -EINVAL (bad config), -EIO / -ERANGE from the hardware, or
 * -ENOMEM. Leaves the spot at the centre. */
int scan_prepare(cam_t *cam, stage_t *stage, const scan_config_t *cfg, const scan_hooks_t *hooks,
                 scan_setup_t *setup, err_t *err);

/* Allocates an empty raster for cfg and setup. Returns 0, -EINVAL (cfg, or the raster rules of
 * scan_limits.h: whole steps, at most SCAN_MAX_POINTS points) or -ENOMEM. */
int scan_raster_init(scan_raster_t *r, const scan_config_t *cfg, const scan_setup_t *setup,
                     err_t *err);

/* Stores a point (e.g. read back from a database) into r: -EINVAL when it does not fit r. */
int scan_raster_put(scan_raster_t *r, const scan_point_t *pt, err_t *err);

void scan_raster_free(scan_raster_t *r);

/* The commanded stage position of raster point index (index < nx * nx). */
stage_pos_t scan_raster_position(const scan_config_t *cfg, const scan_setup_t *setup, int nx,
                                 size_t index);

/* Captures raster points first..count-1 (sets the setup's exposure and gain first), handing each
 * to hooks->point and storing it into raster when not NULL (initialised for the same cfg and
 * setup). Returns 0, -ECANCELED (stopped: points before the one in flight are delivered), or a
 * hardware / memory error. */
int scan_raster_run(cam_t *cam, stage_t *stage, const scan_config_t *cfg, const scan_setup_t *setup,
                    size_t first, const scan_hooks_t *hooks, scan_raster_t *raster, err_t *err);

/* scan_prepare, then scan_raster_run from point 0 into *raster (initialised here; the caller
 * frees it, also after an error). */
int scan_run(cam_t *cam, stage_t *stage, const scan_config_t *cfg, const scan_hooks_t *hooks,
             scan_raster_t *raster, err_t *err);

/* The response of sub-frame pixel (dcol, drow) (the POI is (0, 0); |dcol|, |drow| <= m/2) at the
 * captured positions strictly inside it, as a scan file: positions relative to that pixel's
 * corner, the means of k frames, and the setup's sensor constants (gain_e_per_dn divided by
 * the analogue gain). *out (scanfile.h) is the caller's (scanfile_free).
 * Returns 0, -EINVAL (pixel outside the sub-frame, unknown constants) or -ENOMEM. */
int scan_extract_pixel(const scan_raster_t *r, int dcol, int drow, struct scanfile *out,
                       err_t *err);
/* The same with all != 0 keeping every captured position (outside the pixel too, positions
 * still relative to its corner): the whole raster for the Wiener baseline and fit/region.h. */
int scan_extract_pixel_region(const scan_raster_t *r, int dcol, int drow, int all,
                              struct scanfile *out, err_t *err);

/* Building blocks of scan_extract_pixel, for rasters kept elsewhere (the server's database):
 * a scan file of n points with the setup's sensor constants (arrays allocated, not filled; the
 * caller's, scanfile_free), and the position of stage point (sx, sy) relative to the corner of
 * sub-frame pixel (dcol, drow), returning 1 when it lies strictly inside that pixel. */
int scan_file_new(const scan_setup_t *setup, int frames, size_t n, struct scanfile *out,
                  err_t *err);
int scan_pixel_coords(const scan_setup_t *setup, int dcol, int drow, double sx, double sy,
                      double *x, double *y);

/* A direct raster inside the POI (the paper's 9 x 9 of fig. 9): n x n points at step_um spacing
 * centred on the POI's centre (they must all lie strictly inside it), k frames of the POI alone
 * at each, with the setup's exposure; no raster of the neighbours. *out as above. */
int scan_grid_pixel(cam_t *cam, stage_t *stage, const scan_config_t *cfg, const scan_setup_t *setup,
                    int n, const scan_hooks_t *hooks, struct scanfile *out, err_t *err);

/* The POI read at n positions (x[k], y[k]) relative to its corner, as scan_grid_pixel reads its
 * grid (k frames of the POI alone at each, the setup's exposure), the points appended to *out (a
 * scan file from scan_file_new or an earlier call: its arrays grow, out->scan follows them), in
 * the order given: the batches of an adaptive scan (fit/adapt_plan.h). Returns 0, -ECANCELED
 * (stopped: the points before stay in *out), -ENOMEM, or the camera's / stage's error (-ERANGE
 * outside the stage's travel). */
int scan_pixel_points(cam_t *cam, stage_t *stage, const scan_config_t *cfg,
                      const scan_setup_t *setup, size_t n, const double *x, const double *y,
                      const scan_hooks_t *hooks, struct scanfile *out, err_t *err);

/* The stage's travel seen from the POI's corner (pixel coordinates, scandata.h): box_um gets
 * x_min, x_max, y_min, y_max, the positions an adaptive scan may propose (fit_adapt_opts_t's
 * box_um). Returns 0 or the stage's error. */
int scan_pixel_box(stage_t *stage, const scan_setup_t *setup, double box_um[4], err_t *err);

/* The sub-frame read at n positions (x[k], y[k]) relative to the POI's corner, as the raster
 * reads its points (k frames of the m x m sub-frame around the POI, the setup's exposure, the
 * raw frames kept when cfg->keep_frames), each point handed to hooks->point with index
 * first + k of count (ix, iy -1: not a raster point) and progress "adaptive": the batches of an
 * adaptive scan stored as raster points are (the server's adaptive scan job). Returns 0,
 * -ECANCELED (stopped, or the handler refused a point: the points before were delivered),
 * -EINVAL (cfg against the camera), -ENOMEM, or the camera's / stage's error. */
int scan_subframe_points(cam_t *cam, stage_t *stage, const scan_config_t *cfg,
                         const scan_setup_t *setup, size_t first, size_t count, size_t n,
                         const double *x, const double *y, const scan_hooks_t *hooks, err_t *err);

#endif
