/* api_scans.c: scans: create (every field validated and named in errors; 202 with the scan and
 * its queued job, committed before the answer), list (filter by sensor and state, paginated),
 * get (state, progress, setup), cancel. The data of a scan (a pixel's raster, a point's frames,
 * its fits) is in api_scandata.c. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_int.h"
#include "fit/adapt_plan.h"
#include "fit/airy.h"
#include "instrument/scan_limits.h"

/* Field id of the scan request (scan_limits.h): its type (400), range and oddness (422), each
 * error naming the field. *v is left alone when the member is absent (the caller's default). */
static int get_field(api_req_t *q, json_t *o, scan_field_id_t id, double *v)
{
    const scan_field_t *f = &scan_fields[id];
    const char *dot = strrchr(f->api, '.'), *key = dot ? dot + 1 : f->api;
    long long n = 0;
    if (!json_object_get(o, key)) return 0;
    if (f->integer ? api_get_int(q, o, key, f->api, 0, (long long)f->min, (long long)f->max, &n)
                   : api_get_num(q, o, key, f->api, 0, f->min, f->max, f->open_min, v))
        return -1;
    if (f->integer) *v = (double)n;
    if (f->odd && n % 2 == 0) {
        api_error(q, 422, "out_of_range", f->api, "%s must be odd (got %lld)", f->api, n);
        return -1;
    }
    return 0;
}

/* Reads optics {wavelength_nm, na} or {spot_radius_um} into sc; -1 after replying. */
static int read_optics(api_req_t *q, json_t *body, storage_scan_t *sc)
{
    static const char *const keys[] = {"wavelength_nm", "na", "spot_radius_um", NULL};
    json_t *o;
    double nm = scan_fields[SCAN_F_WAVELENGTH_NM].def, na = NAN, R = NAN;
    if (api_get_obj(q, body, "optics", "optics", &o)) return -1;
    if (o && (api_no_unknown(q, o, "optics.", keys) || get_field(q, o, SCAN_F_WAVELENGTH_NM, &nm) ||
              get_field(q, o, SCAN_F_NA, &na) || get_field(q, o, SCAN_F_SPOT_RADIUS_UM, &R)))
        return -1;
    if (isfinite(na) && isfinite(R)) {
        api_error(q, 422, "invalid", "optics.spot_radius_um",
                  "give optics.na or optics.spot_radius_um, not both");
        return -1;
    }
    /* paper eq. 1 (fit/airy.h), solved for whichever is not given */
    int have_na = isfinite(na);
    if (isfinite(R)) na = fit_spot_na(nm * 1e-3, R);
    if (!isfinite(na)) na = scan_fields[SCAN_F_NA].def;
    if (!isfinite(R)) R = fit_spot_radius_um(nm * 1e-3, na);
    if (!(na > 0 && na <= SCAN_NA_MAX)) {
        api_error(q, 422, "out_of_range", "optics.spot_radius_um",
                  "a spot radius of %g um at %g nm needs NA %g, outside 0..%g", R, nm, na,
                  SCAN_NA_MAX);
        return -1;
    }
    if (!(R > 0 && isfinite(R))) { /* only at the ends of double precision */
        const char *f = have_na ? "optics.na" : "optics.wavelength_nm";
        api_error(q, 422, "out_of_range", f,
                  "%g nm and NA %g give a spot radius of %g um by eq. 1: not a usable radius", nm,
                  na, R);
        return -1;
    }
    sc->wavelength_um = nm * 1e-3;
    sc->na = na;
    sc->spot_radius_um = R;
    return 0;
}

/* Reads raster {area_px, step_um, sub_px, frames} into sc; -1 after replying. */
static int read_raster(api_req_t *q, json_t *body, storage_scan_t *sc)
{
    static const char *const keys[] = {"area_px", "step_um", "sub_px", "frames", NULL};
    json_t *o;
    double area = scan_fields[SCAN_F_AREA_PX].def, step = scan_fields[SCAN_F_STEP_UM].def,
           sub = scan_fields[SCAN_F_SUB_PX].def, frames = scan_fields[SCAN_F_FRAMES].def;
    err_t err = {{0}};
    if (api_get_obj(q, body, "raster", "raster", &o)) return -1;
    if (o && (api_no_unknown(q, o, "raster.", keys) || get_field(q, o, SCAN_F_AREA_PX, &area) ||
              get_field(q, o, SCAN_F_STEP_UM, &step) || get_field(q, o, SCAN_F_SUB_PX, &sub) ||
              get_field(q, o, SCAN_F_FRAMES, &frames)))
        return -1;
    if (scan_check_samples((int)frames, (int)sub, "raster.frames", &err)) {
        api_error(q, 422, "out_of_range", "raster.frames", "%s", err.msg);
        return -1;
    }
    sc->area_px = (int)area;
    sc->step_um = step;
    sc->sub_px = (int)sub;
    sc->frames = (int)frames;
    return 0;
}

/* Reads strategy {"kind": "raster"} or {"kind": "adaptive", "target_err", "max_points", "batch",
 * "start_grid"} into *s (absent: the raster); -1 after replying. */
static int read_strategy(api_req_t *q, json_t *body, srv_strategy_t *s)
{
    static const char *const raster_keys[] = {"kind", NULL};
    static const char *const adaptive_keys[] = {"kind",  "target_err", "max_points",
                                                "batch", "start_grid", NULL};
    json_t *o;
    const char *kind = NULL;
    long long max_points = FIT_ADAPT_MAX_POINTS, batch = FIT_ADAPT_BATCH,
              grid = FIT_ADAPT_START_GRID;
    *s = srv_strategy_default();
    if (api_get_obj(q, body, "strategy", "strategy", &o)) return -1;
    if (!o) return 0;
    if (api_get_str(q, o, "kind", "strategy.kind", 1, 31, &kind)) return -1;
    if (strcmp(kind, "raster") == 0) return api_no_unknown(q, o, "strategy.", raster_keys);
    if (strcmp(kind, "adaptive")) {
        api_error(q, 422, "out_of_range", "strategy.kind",
                  "strategy.kind must be raster or adaptive (got '%s')", kind);
        return -1;
    }
    if (api_no_unknown(q, o, "strategy.", adaptive_keys) ||
        api_get_num(q, o, "target_err", "strategy.target_err", 0, 0, 1, 1, &s->target_err) ||
        api_get_int(q, o, "start_grid", "strategy.start_grid", 0, 2, SRV_ADAPT_START_GRID_MAX,
                    &grid) ||
        api_get_int(q, o, "batch", "strategy.batch", 0, 1, SRV_ADAPT_BATCH_MAX, &batch) ||
        api_get_int(q, o, "max_points", "strategy.max_points", 0, 1, SRV_ADAPT_MAX_POINTS,
                    &max_points))
        return -1;
    if (max_points < grid * grid) {
        api_error(q, 422, "out_of_range", "strategy.max_points",
                  "strategy.max_points %lld is below the starting raster's %lld points "
                  "(strategy.start_grid %lld)",
                  max_points, grid * grid, grid);
        return -1;
    }
    s->adaptive = 1;
    s->max_points = (int)max_points;
    s->batch = (int)batch;
    s->start_grid = (int)grid;
    return 0;
}

/* The POI must be on the sensor with the whole sub-frame, the raster must be whole steps and at
 * most SCAN_MAX_POINTS points (scan_limits.h), and what the scan would store at most
 * --max-scan-bytes. */
static int check_geometry(api_req_t *q, const storage_sensor_t *sn, const storage_scan_t *sc,
                          const srv_strategy_t *strategy)
{
    int h = sc->sub_px / 2;
    const char *f = NULL;
    err_t err = {{0}};
    if (sc->poi_col - h < 0 || sc->poi_col + h >= sn->n_cols)
        f = "poi.col";
    else if (sc->poi_row - h < 0 || sc->poi_row + h >= sn->n_rows)
        f = "poi.row";
    if (f) {
        api_error(q, 422, "out_of_range", f,
                  "the %dx%d sub-frame around pixel (%d, %d) must lie "
                  "on the %d x %d sensor",
                  sc->sub_px, sc->sub_px, sc->poi_col, sc->poi_row, sn->n_cols, sn->n_rows);
        return -1;
    }
    /* and on the camera ipsd holds, when it said its size at start (a GenICam camera) */
    const cam_info_t *cam = srv_camera(q->srv);
    if (cam->width > 0 && cam->height > 0 &&
        (sc->poi_col + h >= cam->width || sc->poi_row + h >= cam->height)) {
        api_error(q, 422, "out_of_range", sc->poi_col + h >= cam->width ? "poi.col" : "poi.row",
                  "the %dx%d sub-frame around pixel (%d, %d) must lie on the %d x %d array of "
                  "the camera (%s %s)",
                  sc->sub_px, sc->sub_px, sc->poi_col, sc->poi_row, cam->width, cam->height,
                  cam->backend, cam->id);
        return -1;
    }
    int nx;
    if (scan_check_raster(sn->pitch_um, sc->area_px, sc->step_um, "raster.step_um", &nx, &err)) {
        api_error(q, 422, "out_of_range", "raster.step_um", "%s", err.msg);
        return -1;
    }
    double per_point = storage_frame_bytes(sc->frames, sc->sub_px), points = (double)nx * nx;
    if (strategy->adaptive) points = strategy->max_points; /* at most its budget */
    double cap = srv_config(q->srv)->max_scan_bytes;
    if (points * per_point > cap) {
        api_error(q, 422, "too_large", "raster",
                  "the scan would store %.4g MiB of frames (%.0f points x %.4g KiB), more "
                  "than ipsd's limit of %.4g MiB (--max-scan-bytes): take fewer points, "
                  "frames or a smaller sub-frame",
                  points * per_point / 1048576, points, per_point / 1024, cap / 1048576);
        return -1;
    }
    return 0;
}

/* Reads and checks a scan request; -1 after replying. */
static int read_scan(api_req_t *q, json_t *o, storage_t *st, storage_scan_t *sc,
                     srv_scan_params_t *p)
{
    static const char *const keys[] = {"sensor_id", "poi",  "optics", "raster",   "exposure_us",
                                       "scene",     "seed", "setup",  "strategy", NULL};
    static const char *const poi_keys[] = {"col", "row", NULL};
    long long sensor_id, col, row;
    double seed = scan_fields[SCAN_F_SEED].def;
    const char *scene = NULL, *setup = NULL;
    json_t *poi;
    storage_sensor_t sn;
    *sc = (storage_scan_t){.exposure_us = scan_fields[SCAN_F_EXPOSURE_US].def};
    *p = srv_scan_params_default();
    if (api_no_unknown(q, o, "", keys) ||
        api_get_int(q, o, "sensor_id", "sensor_id", 1, 1, INT64_MAX, &sensor_id) ||
        api_get_obj(q, o, "poi", "poi", &poi))
        return -1;
    if (!poi) {
        api_error(q, 422, "missing", "poi", "poi {col, row} is required");
        return -1;
    }
    if (api_no_unknown(q, poi, "poi.", poi_keys) ||
        api_get_int(q, poi, "col", "poi.col", 1, 0, 1000000, &col) ||
        api_get_int(q, poi, "row", "poi.row", 1, 0, 1000000, &row) || read_optics(q, o, sc) ||
        read_raster(q, o, sc) || get_field(q, o, SCAN_F_EXPOSURE_US, &sc->exposure_us) ||
        api_get_str(q, o, "scene", "scene", 0, 31, &scene) || get_field(q, o, SCAN_F_SEED, &seed) ||
        api_get_str(q, o, "setup", "setup", 0, 31, &setup) || read_strategy(q, o, &p->strategy))
        return -1;
    if (setup && strcmp(setup, "paper") && strcmp(setup, "none")) {
        api_error(q, 422, "out_of_range", "setup", "setup must be paper or none (got '%s')", setup);
        return -1;
    }
    p->setup_none = setup && strcmp(setup, "none") == 0;
    if (scene && strcmp(scene, "uniform") && strcmp(scene, "paperlike")) {
        api_error(q, 422, "out_of_range", "scene", "scene must be one of " SRV_SCENES " (got '%s')",
                  scene);
        return -1;
    }
    if (scene && strcmp(srv_config(q->srv)->bench, "sim")) {
        api_error(q, 422, "invalid", "scene", "scene is for the simulated bench only");
        return -1;
    }
    if (scene) snprintf(p->scene, sizeof p->scene, "%s", scene);
    p->seed = (unsigned long)seed;
    sc->sensor_id = sensor_id;
    sc->poi_col = (int)col;
    sc->poi_row = (int)row;
    err_t err = {{0}};
    int ret = storage_sensor_get(st, sensor_id, &sn, &err);
    if (ret) {
        api_error_rc(q, ret == -ENOENT ? -EINVAL : ret, "sensor_id", err.msg);
        return -1;
    }
    ret = check_geometry(q, &sn, sc, &p->strategy);
    storage_sensor_free(&sn);
    return ret;
}

/* The scan job of a scan (0 when it has none). */
static int64_t scan_job_id(storage_t *st, int64_t scan_id)
{
    storage_job_list_t l;
    int64_t id = 0;
    if (storage_job_list(st, STORAGE_JOB_SCAN, STORAGE_ANY, scan_id, 1, 0, &l, NULL)) return 0;
    if (l.n) id = l.items[0].id;
    storage_job_list_free(&l);
    return id;
}

/* The scan's strategy (from its job's params: a raster when it has none) into the Scan o. */
static void add_strategy_params(json_t *o, const char *params)
{
    srv_scan_params_t p = srv_scan_params_default();
    if (o && params) srv_scan_params_parse(params, &p, NULL);
    if (o) json_object_set_new(o, "strategy", srv_strategy_json(&p.strategy));
}

static void add_strategy(json_t *o, const storage_job_t *j)
{
    add_strategy_params(o, j ? j->params : NULL);
}

/* {"scan": ..., "job": ...} of a scan and a job, read back from the database. */
static void reply_scan_job(api_req_t *q, storage_t *st, unsigned status, int64_t scan_id,
                           int64_t job_id)
{
    storage_scan_t sc;
    storage_job_t j;
    err_t err = {{0}};
    int ret = storage_scan_get(st, scan_id, &sc, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    if (job_id && (ret = storage_job_get(st, job_id, &j, &err))) {
        storage_scan_free(&sc);
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    json_t *scan = api_enc_scan(&sc);
    add_strategy(scan, job_id ? &j : NULL);
    api_reply_json(q, status,
                   json_pack("{s:o, s:o}", "scan", scan, "job",
                             job_id ? api_enc_job(&j) : json_null()));
    if (job_id) storage_job_free(&j);
    storage_scan_free(&sc);
}

void api_h_scans_create(api_req_t *q)
{
    json_t *o = api_body_object(q);
    storage_t *st = o ? api_db(q) : NULL;
    storage_scan_t sc;
    srv_scan_params_t p;
    int64_t scan_id, job_id;
    err_t err = {{0}};
    if (st && read_scan(q, o, st, &sc, &p) == 0) {
        int ret = srv_scan_submit(q->srv, st, &sc, &p, &scan_id, &job_id, &err);
        if (ret == -ENOTSUP) {
            api_error(q, 409, "conflict", NULL, "%s", err.msg);
        } else if (ret) {
            api_error_rc(q, ret, NULL, err.msg);
        } else {
            reply_scan_job(q, st, 202, scan_id, job_id);
            char loc[64];
            snprintf(loc, sizeof loc, "/api/scans/%lld", (long long)scan_id);
            if (q->resp) MHD_add_response_header(q->resp, MHD_HTTP_HEADER_LOCATION, loc);
        }
    }
    json_decref(o);
}

void api_h_scans_list(api_req_t *q)
{
    long long sensor, limit, offset;
    int state;
    storage_t *st;
    storage_scan_list_t l;
    err_t err = {{0}};
    if (api_query_int(q, "sensor", 0, 0, INT64_MAX, &sensor) ||
        api_query_page(q, &limit, &offset) || api_query_state(q, &state) || !(st = api_db(q)))
        return;
    int ret = storage_scan_list(st, sensor, state, (int)limit, (int)offset, &l, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    json_t *items = json_array();
    for (size_t i = 0; items && i < l.n; i++) {
        json_t *o = api_enc_scan(&l.items[i]);
        add_strategy_params(o, l.items[i].job_params);
        json_array_append_new(items, o);
    }
    api_reply_json(q, 200, api_enc_page(items, l.total, limit, offset));
    storage_scan_list_free(&l);
}

void api_h_scan_get(api_req_t *q)
{
    storage_t *st;
    storage_scan_t sc;
    int64_t id;
    char *setup = NULL;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "scan", &id) || !(st = api_db(q))) return;
    int ret = storage_scan_get(st, id, &sc, &err);
    if (ret == 0) ret = storage_scan_get_setup(st, id, &setup, &err);
    if (ret) {
        if (ret != -ENOENT) storage_scan_free(&sc);
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    json_t *o = api_enc_scan(&sc);
    int64_t job = scan_job_id(st, id);
    storage_job_t j;
    if (job && storage_job_get(st, job, &j, NULL) == 0) {
        add_strategy(o, &j);
        storage_job_free(&j);
    } else {
        add_strategy(o, NULL);
    }
    if (o) {
        json_object_set_new(o, "job_id", job ? json_integer(job) : json_null());
        json_t *su = setup ? json_loads(setup, 0, NULL) : NULL;
        json_object_set_new(o, "setup", su ? su : json_null());
    }
    api_reply_json(q, 200, o);
    free(setup);
    storage_scan_free(&sc);
}

void api_h_scan_resume(api_req_t *q)
{
    storage_t *st;
    int64_t id, job = 0;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "scan", &id) || !(st = api_db(q))) return;
    int ret = srv_scan_resume(q->srv, st, id, &job, &err);
    if (ret == -ENOTSUP)
        api_error(q, 409, "conflict", NULL, "%s", err.msg);
    else if (ret)
        api_error_rc(q, ret, NULL, err.msg);
    else
        reply_scan_job(q, st, 202, id, job);
}

void api_h_scan_cancel(api_req_t *q)
{
    storage_t *st;
    storage_scan_t sc;
    int64_t id;
    int changed = 0;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "scan", &id) || !(st = api_db(q))) return;
    int ret = storage_scan_get(st, id, &sc, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    int64_t job = scan_job_id(st, id);
    if (job) ret = srv_job_cancel(q->srv, st, job, &changed, &err);
    if (ret)
        api_error_rc(q, ret, NULL, err.msg);
    else if (!changed)
        api_error(q, 409, "conflict", NULL, "scan %lld is %s: nothing to cancel", (long long)id,
                  storage_state_name(sc.state));
    else
        reply_scan_job(q, st, 200, id, job);
    storage_scan_free(&sc);
}
