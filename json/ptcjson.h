/* ptcjson.h: the JSON form of a photon-transfer result (fit/ptc.h), as `ips ptc` prints it
 * (docs/contracts.md): the fitted figures and the per-level table. New reference owned by the
 * caller, or NULL when out of memory. */
#ifndef IPSD_JSON_PTCJSON_H
#define IPSD_JSON_PTCJSON_H

#include <stddef.h>

#include <jansson.h>

#include "fit/ptc.h"

json_t *ptcjson_result(const fit_ptc_result_t *r, const fit_ptc_level_t *lv, size_t n);

#endif
