/* ptcjson.c: the photon-transfer result as JSON (ptcjson.h). */
#include "json/fitjson.h"
#include "json/ptcjson.h"

json_t *ptcjson_result(const fit_ptc_result_t *r, const fit_ptc_level_t *lv, size_t n)
{
    json_t *levels = json_array();
    for (size_t i = 0; levels && i < n; i++) {
        json_t *o =
            json_pack("{s:o, s:o, s:o, s:o, s:o}", "exposure_us", fitjson_num(lv[i].exposure_us),
                      "mu", fitjson_num(lv[i].mu_y), "sigma2", fitjson_num(lv[i].s2_y), "mu_dark",
                      fitjson_num(lv[i].mu_dark), "sigma2_dark", fitjson_num(lv[i].s2_dark));
        if (!o || json_array_append_new(levels, o)) {
            json_decref(levels);
            return NULL;
        }
    }
    if (!levels) return NULL;
    return json_pack(
        "{s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:[I, I], s:[I, I], "
        "s:I, s:o}",
        "K", fitjson_num(r->K), "K_err", fitjson_num(r->K_err), "gain_e_per_dn",
        fitjson_num(r->gain_e_per_dn), "read_noise_e", fitjson_num(r->read_noise_e),
        "read_noise_dn", fitjson_num(r->read_noise_dn), "dark_dn", fitjson_num(r->dark_dn),
        "sigma2_dark", fitjson_num(r->s2_dark), "saturation_dn", fitjson_num(r->saturation_dn),
        "linearity_error_pct", fitjson_num(r->linearity_error_pct), "linearity_min_pct",
        fitjson_num(r->le_min_pct), "linearity_max_pct", fitjson_num(r->le_max_pct), "fit_levels",
        (json_int_t)r->fit_lo, (json_int_t)r->fit_hi, "linearity_levels", (json_int_t)r->lin_lo,
        (json_int_t)r->lin_hi, "saturation_level", (json_int_t)r->sat_index, "levels", levels);
}
