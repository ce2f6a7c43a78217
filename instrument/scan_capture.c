/* scan_capture.c: what every step of the scan procedure does at a stage position: move there and
 * average k frames of a region (mean and variance), and look at the stop flag and report progress
 * through the hooks (scan_int.h). */
#include "scan_int.h"

#include <math.h>
#include <stdatomic.h>

int scan_stopped(const scan_hooks_t *h)
{
    return h && h->stop && atomic_load(h->stop);
}

void scan_progress(const scan_hooks_t *h, const char *phase, size_t done, size_t total)
{
    if (h && h->progress) h->progress(phase, done, total, h->user);
}

/* Welford's running mean and variance over the k frames. */
int scan_capture_at(cam_t *cam, stage_t *stage, const stage_pos_t *pos, const cam_roi_t *roi, int k,
                    int use_expected, struct scan_capture *c, err_t *err)
{
    int rc = stage_move(stage, pos, err);
    if (rc == 0) rc = stage_get_position(stage, &c->reported, err);
    if (rc) return rc;
    size_t npx = (size_t)roi->width * roi->height;
    for (size_t q = 0; q < npx; q++)
        c->mean[q] = c->var[q] = 0;
    c->left_out_dn = 0;
    for (int f = 0; f < k; f++) {
        cam_frame_t fr;
        rc = cam_capture(cam, roi, &fr, err);
        if (rc) return rc;
        if (f == 0) {
            c->t0_ns = fr.timestamp_ns;
            c->exposure_us = fr.exposure_us;
            c->gain = fr.gain;
        }
        if (fr.left_out_dn > c->left_out_dn) c->left_out_dn = fr.left_out_dn;
        if (c->ts_ns) c->ts_ns[f] = fr.timestamp_ns;
        if (c->ids) c->ids[f] = fr.camera_frame_id;
        for (size_t q = 0; q < npx; q++) {
            double x = use_expected && fr.expected_dn ? fr.expected_dn[q] : fr.dn[q];
            double d = x - c->mean[q];
            c->mean[q] += d / (f + 1);
            c->var[q] += d * (x - c->mean[q]);
            if (c->raw) c->raw[(size_t)f * npx + q] = fr.dn[q];
        }
        cam_frame_free(&fr);
    }
    for (size_t q = 0; q < npx; q++)
        c->var[q] = k > 1 ? c->var[q] / (k - 1) : NAN;
    return 0;
}

scan_point_t scan_point_of_capture(const struct scan_capture *c, size_t index, size_t count,
                                   int ix, int iy, const stage_pos_t *pos, int k, int m)
{
    return (scan_point_t){.index = index,
                          .count = count,
                          .ix = ix,
                          .iy = iy,
                          .commanded = *pos,
                          .reported = c->reported,
                          .exposure_us = c->exposure_us,
                          .gain = c->gain,
                          .timestamp_ns = c->t0_ns,
                          .frames = k,
                          .width = m,
                          .height = m,
                          .mean_dn = c->mean,
                          .var_dn = c->var,
                          .raw = c->raw,
                          .frame_timestamps_ns = c->ts_ns,
                          .camera_frame_ids = c->ids,
                          .left_out_dn = c->left_out_dn};
}
