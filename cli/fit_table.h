/* fit_table.h: the human-readable report of `ips fit --table`: the model-selection table,
 * the fitted geometry, the best map as numbers and as a shaded picture, the shrunk and the kriged
 * map, the F-test and the Wiener baseline. */
#ifndef IPSD_CLI_FIT_TABLE_H
#define IPSD_CLI_FIT_TABLE_H

#include <stdio.h>

#include "fit/geometry.h"
#include "fit/model.h"
#include "fit/wiener.h"

/* Prints the report to f. geometry, ftest and wiener may be NULL (not asked); kriged_error: why the kriged
 * map asked for is missing (NULL: not asked, or it is in sw->kriged). total_ms: the run time. */
void fit_table_print(FILE *f, const char *path, const fit_scan_t *scan, const fit_sweep_t *sw,
                     const fit_geometry_t *geometry, const fit_ftest_t *ftest, const fit_wiener_t *wiener,
                     const char *kriged_error, double total_ms);

#endif
