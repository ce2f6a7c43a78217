/* refdata.h: loads the published reference files of tests/data (independent values) for the
 * fit tests. Header-only; each test includes it once. */
#ifndef IPSD_TEST_REFDATA_H
#define IPSD_TEST_REFDATA_H

#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>

#include "fit/scandata.h"

/* The reference scan as a fit_scan_t; arrays owned by the struct (free with ref_scan_free). */
typedef struct ref_scan {
    fit_scan_t scan;
    double *buf;
    json_t *root;
} ref_scan_t;

static double ref_num(json_t *o, const char *key) { return json_number_value(json_object_get(o, key)); }

static int ref_scan_load(const char *path, ref_scan_t *rs)
{
    json_error_t je;
    rs->root = json_load_file(path, 0, &je);
    if (!rs->root) {
        fprintf(stderr, "cannot read %s: %s\n", path, je.text);
        return -1;
    }
    json_t *xs = json_object_get(rs->root, "x_um"), *ys = json_object_get(rs->root, "y_um"),
           *ss = json_object_get(rs->root, "signal_dn");
    size_t n = json_array_size(xs);
    rs->buf = malloc(sizeof(double) * 3 * (n ? n : 1));
    for (size_t k = 0; k < n; k++) {
        rs->buf[k] = json_number_value(json_array_get(xs, k));
        rs->buf[n + k] = json_number_value(json_array_get(ys, k));
        rs->buf[2 * n + k] = json_number_value(json_array_get(ss, k));
    }
    rs->scan = (fit_scan_t){.n = n, .x_um = rs->buf, .y_um = rs->buf + n,
                            .signal_dn = rs->buf + 2 * n,
                            .pitch_um = ref_num(rs->root, "pitch_um"),
                            .spot_radius_um = ref_num(rs->root, "spot_radius_um"),
                            .bias_dn = ref_num(rs->root, "bias_dn"),
                            .gain_e_per_dn = ref_num(rs->root, "gain_e_per_dn"),
                            .read_noise_e = ref_num(rs->root, "read_noise_e"),
                            .frames = (int)json_integer_value(json_object_get(rs->root, "frames")),
                            .full_scale_dn = FIT_FULL_SCALE_DEFAULT};
    return 0;
}

static void ref_scan_free(ref_scan_t *rs)
{
    free(rs->buf);
    json_decref(rs->root);
}

#endif
