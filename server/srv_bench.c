/* srv_bench.c: opening the instrument of a scan (see srv_bench.h). */
#include "srv_bench.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A real stage answers: opened and closed again. */
static int check_stage(const char *stage, err_t *err)
{
    int is_sim;
    err_t e;
    if (stage_url_check(stage, &is_sim, &e)) return err_set(err, -EINVAL, "--stage: %s", e.msg);
    if (is_sim) return 0;
    stage_t *st;
    int ret = stage_open_url(stage, &st, &e);
    stage_close(st);
    return ret ? err_set(err, ret, "--stage: %s", e.msg) : 0;
}

const char *srv_bench_split(const char *bench, char *kind, size_t kind_size)
{
    size_t len = strcspn(bench, ":");
    snprintf(kind, kind_size, "%.*s", (int)len, bench);
    return bench[len] == ':' ? bench + len + 1 : NULL;
}

int srv_bench_check(const char *bench, const char *stage, cam_info_t *camera, err_t *err)
{
    char kind[32];
    const char *id = srv_bench_split(bench, kind, sizeof kind);
    memset(camera, 0, sizeof *camera);
    int ret = check_stage(stage, err);
    if (ret) return ret;
    if (strcmp(kind, "sim") == 0) {
        snprintf(camera->backend, sizeof camera->backend, "sim");
        snprintf(camera->model, sizeof camera->model, "simulated bench");
        return 0;
    }
    if (strcmp(kind, "none") == 0) {
        snprintf(camera->backend, sizeof camera->backend, "none");
        snprintf(camera->model, sizeof camera->model, "no instrument");
        return 0;
    }
    cam_info_t *infos = NULL;
    size_t n = 0, i = 0;
    ret = cam_list(kind, &infos, &n, err);
    if (ret) return ret;
    while (id && i < n && strcmp(infos[i].id, id) != 0)
        i++;
    if (i < n) *camera = infos[i];
    free(infos);
    if (n == 0) return err_set(err, -ENODEV, "--bench %s: no camera found by %s", bench, kind);
    if (i == n)
        return err_set(err, -ENODEV,
                       "--bench %s: no camera '%s' found by %s (%zu other%s: see "
                       "ipsd --list-cameras)",
                       bench, id, kind, n, n == 1 ? "" : "s");
    if (strcmp(kind, "aravis") != 0) return 0;
    /* a GenICam camera is opened once: one that cannot do what a scan needs (no monochrome
     * pixel format, no exposure time) is refused now, naming the feature, and its array size
     * and pixel format are known to the API's checks */
    cam_t *cam;
    err_t e;
    if ((ret = cam_open(kind, camera->id, &cam, &e)))
        return err_set(err, ret, "--bench %s: %s", bench, e.msg);
    ret = cam_get_info(cam, camera, &e);
    cam_close(cam);
    return ret ? err_set(err, ret, "--bench %s: %s", bench, e.msg) : 0;
}

/* The simulated bench as the scan's sensor (from the database), optics, scene and seed. */
static int open_sim(const storage_sensor_t *sn, const storage_scan_t *sc,
                    const srv_scan_params_t *p, int (*frame_fault)(void *, unsigned long long),
                    void *ctx, srv_bench_t *b, err_t *err)
{
    sim_config_t c = sim_config_default();
    c.scene = p->scene;
    c.sensor.cols = sn->n_cols;
    c.sensor.rows = sn->n_rows;
    c.sensor.pitch_um = sn->pitch_um;
    c.sensor.gain_e_per_dn = sn->gain_e_per_dn;
    c.sensor.read_noise_e = sn->read_noise_e;
    c.sensor.bias_dn = sn->bias_dn;
    c.sensor.full_scale_dn = sn->full_scale_dn;
    c.wavelength_um = sc->wavelength_um;
    c.na = sc->na;
    c.radius_um = sc->spot_radius_um;
    c.seed = p->seed;
    c.stage.seed = p->seed;
    c.frame_fault = frame_fault;
    c.frame_fault_ctx = ctx;
    int ret = sim_open(&c, &b->sim, err);
    if (ret) return ret;
    b->cam = sim_camera(b->sim);
    b->stage = sim_stage(b->sim);
    b->start = sim_pixel_centre(b->sim, sc->poi_col, sc->poi_row);
    return 0;
}

int srv_bench_open(const char *bench, const char *stage, const storage_sensor_t *sn,
                   const storage_scan_t *sc, const srv_scan_params_t *p,
                   int (*frame_fault)(void *, unsigned long long), void *ctx, double timeout_s,
                   srv_bench_t *b, err_t *err)
{
    memset(b, 0, sizeof *b);
    char kind[32];
    const char *id = srv_bench_split(bench, kind, sizeof kind);
    int ret, sim_stage_only = 1;
    if ((ret = stage_url_check(stage, &sim_stage_only, err))) return ret;
    if (strcmp(kind, "sim") == 0) {
        ret = open_sim(sn, sc, p, frame_fault, ctx, b, err);
        if (ret == 0) ret = cam_set_timeout(b->cam, timeout_s, err);
        if (ret || sim_stage_only) return ret;
        /* a real stage leads, the simulated bench's stage follows what it reports */
        stage_t *lead;
        if ((ret = stage_open_url(stage, &lead, err))) return ret;
        return stage_open_follow(lead, sim_stage(b->sim), &b->stage, err);
    }
    ret = cam_open(kind, id, &b->cam, err);
    if (ret == 0) ret = cam_set_timeout(b->cam, timeout_s, err);
    if (ret == 0) ret = stage_open_url(stage, &b->stage, err);
    /* no calibrated mount: the POI's centre in stage coordinates is its sensor position */
    b->start =
        (stage_pos_t){(sc->poi_col + 0.5) * sn->pitch_um, (sc->poi_row + 0.5) * sn->pitch_um, 0};
    return ret;
}

void srv_bench_close(srv_bench_t *b)
{
    if (!b) return;
    if (b->sim) {
        if (b->stage != sim_stage(b->sim)) stage_close(b->stage); /* a follower of a real stage */
        sim_close(b->sim);
    } else {
        cam_close(b->cam);
        stage_close(b->stage);
    }
    memset(b, 0, sizeof *b);
}
