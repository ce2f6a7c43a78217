/* api_sensors.c: the sensors: list, create (validated; the constants not given default to the
 * paper's sensor), get. */
#include <errno.h>
#include <string.h>

#include "api_int.h"

/* The smallest pitch accepted: no sensor has pixels below 0.5 um, and a pitch near zero (5e-324
 * was accepted once) only fails later, in the scan, as a NaN map. */
#define SENSOR_PITCH_MIN_UM 0.1

void api_h_sensors_list(api_req_t *q)
{
    storage_t *st;
    storage_sensor_list_t l;
    long long limit, offset;
    err_t err = {{0}};
    if (api_query_page(q, &limit, &offset) || !(st = api_db(q))) return;
    int ret = storage_sensor_list(st, (int)limit, (int)offset, &l, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    json_t *items = json_array();
    for (size_t i = 0; items && i < l.n; i++)
        json_array_append_new(items, api_enc_sensor(&l.items[i]));
    api_reply_json(q, 200, api_enc_page(items, l.total, limit, offset));
    storage_sensor_list_free(&l);
}

/* Reads the sensor of a create body into *s; -1 after replying. */
static int read_sensor(api_req_t *q, json_t *o, storage_sensor_t *s)
{
    static const char *const keys[] = {
        "model",         "serial",       "n_cols",  "n_rows",        "pitch_um",
        "gain_e_per_dn", "read_noise_e", "bias_dn", "full_scale_dn", NULL};
    /* the paper's sensor (6 um pitch, G = 3.153 e-/DN, 5.67 e-, B = 100 DN, 14 bit) */
    long long cols = 256, rows = 256;
    double pitch = 6.0, gain = 3.153, noise = 5.67, bias = 100.0, full = 16383.0;
    const char *model, *serial;
    if (api_no_unknown(q, o, "", keys) || api_get_str(q, o, "model", "model", 1, 128, &model) ||
        api_get_str(q, o, "serial", "serial", 1, 128, &serial) ||
        api_get_int(q, o, "n_cols", "n_cols", 0, 1, 1000000, &cols) ||
        api_get_int(q, o, "n_rows", "n_rows", 0, 1, 1000000, &rows) ||
        api_get_num(q, o, "pitch_um", "pitch_um", 0, SENSOR_PITCH_MIN_UM, 1000, 0, &pitch) ||
        api_get_num(q, o, "gain_e_per_dn", "gain_e_per_dn", 0, 0, 1e6, 1, &gain) ||
        api_get_num(q, o, "read_noise_e", "read_noise_e", 0, 0, 1e6, 0, &noise) ||
        api_get_num(q, o, "bias_dn", "bias_dn", 0, -1e9, 1e9, 0, &bias) ||
        api_get_num(q, o, "full_scale_dn", "full_scale_dn", 0, 0, 1e9, 1, &full))
        return -1;
    if (!(bias < full)) {
        api_error(q, 422, "out_of_range", "bias_dn",
                  "bias_dn (%g) must be below full_scale_dn "
                  "(%g)",
                  bias, full);
        return -1;
    }
    *s = (storage_sensor_t){.model = (char *)model,
                            .serial = (char *)serial,
                            .n_cols = (int)cols,
                            .n_rows = (int)rows,
                            .pitch_um = pitch,
                            .gain_e_per_dn = gain,
                            .read_noise_e = noise,
                            .bias_dn = bias,
                            .full_scale_dn = full};
    return 0;
}

void api_h_sensors_create(api_req_t *q)
{
    json_t *o = api_body_object(q);
    storage_sensor_t s, got;
    storage_t *st;
    int64_t id = 0;
    err_t err = {{0}};
    if (!o) return;
    if (read_sensor(q, o, &s) == 0 && (st = api_db(q))) {
        int ret = storage_sensor_create(st, &s, &id, &err);
        if (ret == -EEXIST)
            api_error(q, 409, "exists", "serial", "sensor %s serial %s exists already", s.model,
                      s.serial);
        else if (ret)
            api_error_rc(q, ret, NULL, err.msg);
        else if ((ret = storage_sensor_get(st, id, &got, &err)))
            api_error_rc(q, ret, NULL, err.msg);
        else {
            api_reply_json(q, 201, api_enc_sensor(&got));
            storage_sensor_free(&got);
        }
    }
    json_decref(o);
}

void api_h_sensor_get(api_req_t *q)
{
    storage_sensor_t s;
    storage_t *st;
    int64_t id;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "sensor", &id) || !(st = api_db(q))) return;
    int ret = storage_sensor_get(st, id, &s, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    api_reply_json(q, 200, api_enc_sensor(&s));
    storage_sensor_free(&s);
}
