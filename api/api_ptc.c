/* api_ptc.c: photon transfer (EMVA 1288) of a sensor: queue a measurement on the instrument
 * (202 with the job), the sensor's measured constants (the newest measurement, with its whole
 * report) and their history, and one measurement by id (docs/api.md, "Photon transfer"). */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "instrument/sim.h"
#include "server/srv_ptc.h"
#include "api_int.h"

/* A measurement; with_result: its whole report (the `ips ptc` document) under "result". */
static json_t *enc_ptc(const storage_ptc_t *p, int with_result)
{
    json_t *o = json_pack("{s:I, s:I, s:o, s:o, s:o, s:o, s:o, s:o, s:o}", "id", (json_int_t)p->id,
                          "sensor_id", (json_int_t)p->sensor_id, "job_id",
                          p->job_id ? json_integer(p->job_id) : json_null(), "gain_e_per_dn",
                          api_num(p->gain_e_per_dn), "read_noise_e", api_num(p->read_noise_e),
                          "dark_dn", api_num(p->dark_dn), "saturation_dn",
                          api_num(p->saturation_dn), "linearity_error_pct",
                          api_num(p->linearity_error_pct), "created_ms", api_time(p->created_ms));
    json_t *doc = p->result ? json_loads(p->result, 0, NULL) : NULL;
    if (o && doc) {
        /* the figures the report has besides the row's: uncertainties and the fit's range */
        json_t *gerr = json_object_get(doc, "gain_err_e_per_dn");
        json_object_set(o, "gain_err_e_per_dn", gerr ? gerr : json_null());
        json_t *kerr = json_object_get(doc, "K_err");
        json_object_set(o, "K_err", kerr ? kerr : json_null());
        if (with_result) json_object_set(o, "result", doc);
    }
    json_decref(doc);
    return o;
}

void api_h_sensor_ptc_create(api_req_t *q)
{
    static const char *const keys[] = {"levels", "roi_px", "flat_e", "seed", NULL};
    json_t *o = api_body_object(q);
    storage_t *st;
    int64_t sensor, job_id;
    err_t err = {{0}};
    if (!o || api_arg_id(q, 0, "sensor", &sensor)) goto out;
    srv_ptc_params_t p = srv_ptc_params_default(sensor);
    long long levels = p.levels, roi = p.roi_px, seed = (long long)p.seed;
    if (api_no_unknown(q, o, "", keys) ||
        api_get_int(q, o, "levels", "levels", 0, 3, 1000, &levels) ||
        api_get_int(q, o, "roi_px", "roi_px", 0, 2, 4096, &roi) ||
        api_get_num(q, o, "flat_e", "flat_e", 0, 0, 1e12, 1, &p.flat_e) ||
        api_get_int(q, o, "seed", "seed", 0, 0, 4294967295LL, &seed) || !(st = api_db(q)))
        goto out;
    /* what the bench can honour, refused now rather than as a failed job (srv_ptc.h) */
    int min_levels = p.flat_e > 0 ? SRV_PTC_LEVELS_MIN : SRV_PTC_LEVELS_MIN_DEFAULT_LAMP;
    if (levels < min_levels) {
        api_error(q, 422, "out_of_range", "levels",
                  "levels must be at least %d (got %lld): the photon-transfer slope needs 4 "
                  "levels below saturation%s",
                  min_levels, levels,
                  p.flat_e > 0 ? "" : ", and the default lamp saturates the series' top fifth "
                                      "(a flat_e below the saturation charge allows 4)");
        goto out;
    }
    if (roi > SRV_PTC_ROI_MAX) {
        api_error(q, 422, "out_of_range", "roi_px",
                  "roi_px must be 2..%d (got %lld): the simulated bench captures at most %d "
                  "pixels at once",
                  SRV_PTC_ROI_MAX, roi, SIM_CAPTURE_PX_MAX);
        goto out;
    }
    p.levels = (int)levels;
    p.roi_px = (int)roi;
    p.seed = (unsigned long)seed;
    int ret = srv_ptc_submit(q->srv, st, &p, &job_id, &err);
    storage_job_t j;
    if (ret == -ENOTSUP)
        api_error(q, 409, "conflict", NULL, "%s", err.msg);
    else if (ret)
        api_error_rc(q, ret, NULL, err.msg);
    else if ((ret = storage_job_get(st, job_id, &j, &err)))
        api_error_rc(q, ret, NULL, err.msg);
    else {
        api_reply_json(q, 202, json_pack("{s:o}", "job", api_enc_job(&j)));
        char loc[64];
        snprintf(loc, sizeof loc, "/api/jobs/%lld", (long long)job_id);
        if (q->resp) MHD_add_response_header(q->resp, MHD_HTTP_HEADER_LOCATION, loc);
        storage_job_free(&j);
    }
out:
    json_decref(o);
}

void api_h_sensor_ptc(api_req_t *q)
{
    storage_t *st;
    storage_sensor_t sn;
    storage_ptc_list_t l;
    int64_t id;
    long long limit;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "sensor", &id) || api_query_int(q, "limit", 50, 1, 1000, &limit) ||
        !(st = api_db(q)))
        return;
    int ret = storage_sensor_get(st, id, &sn, &err);
    if (ret == 0) {
        storage_sensor_free(&sn);
        ret = storage_ptc_history(st, id, (int)limit, &l, &err);
    }
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    json_t *history = json_array();
    for (size_t i = 0; history && i < l.n; i++)
        json_array_append_new(history, enc_ptc(&l.items[i], 0));
    /* the newest is the sensor's measured constants, the ones its fits use (docs/api.md) */
    json_t *current = l.n ? enc_ptc(&l.items[0], 1) : json_null();
    api_reply_json(q, 200,
                   json_pack("{s:I, s:o, s:o}", "sensor_id", (json_int_t)id, "current", current,
                             "history", history));
    storage_ptc_list_free(&l);
}

void api_h_ptc_get(api_req_t *q)
{
    storage_t *st;
    storage_ptc_t p;
    int64_t id;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "photon-transfer measurement", &id) || !(st = api_db(q))) return;
    int ret = storage_ptc_get(st, id, &p, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    api_reply_json(q, 200, enc_ptc(&p, 1));
    storage_ptc_free(&p);
}
