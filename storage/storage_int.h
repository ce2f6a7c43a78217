/* storage_int.h: what the files of storage/ share and nobody else sees: the handle, the ids of
 * the prepared statements (their SQL is in storage_sql.c), the column lists the row readers
 * depend on, and small checked functions for binding, reading, transactions and BLOBs. */
#ifndef IPSD_STORAGE_INT_H
#define IPSD_STORAGE_INT_H

#include <stdatomic.h>
#include <stdint.h>

#include "storage/storage.h"
#include "sqldb.h"

/* Every statement the code runs after open, prepared once per connection on first use. */
enum stg_id {
    STG_BEGIN_WRITE,
    STG_BEGIN_READ,
    STG_COMMIT,
    STG_ROLLBACK,
    STG_USER_VERSION,
    STG_PAGE_COUNT,
    STG_FREELIST_COUNT,
    STG_SENSOR_INSERT,
    STG_SENSOR_GET,
    STG_SENSOR_FIND,
    STG_SENSOR_LIST,
    STG_SENSOR_COUNT,
    STG_SCAN_INSERT,
    STG_SCAN_GET,
    STG_SCAN_COUNT,
    STG_SCAN_LIST,
    STG_SCAN_SET_STATE,
    STG_SCAN_ADD_POINT,
    STG_SCAN_CANCEL,
    STG_SCAN_SET_SETUP,
    STG_SCAN_GET_SETUP,
    STG_SCAN_SET_TOTAL,
    STG_FRAME_INSERT,
    STG_FRAME_TIMES_INSERT,
    STG_FRAME_TIMES_GET,
    STG_FRAME_GET,
    STG_FRAME_HEAD,
    STG_FRAME_LAST,
    STG_FRAME_RASTER,
    STG_FRAME_MEANS,
    STG_JOB_INSERT,
    STG_JOB_GET,
    STG_JOB_NEXT,
    STG_JOB_START,
    STG_JOB_HEARTBEAT,
    STG_JOB_FINISH,
    STG_JOB_CANCEL,
    STG_JOB_STATE,
    STG_JOB_ABANDON,
    STG_JOB_REQUEUE,
    STG_JOB_RELEASE,
    STG_JOB_COUNT,
    STG_JOB_LIST,
    STG_JOB_SET_FIT,
    STG_JOB_STEP,
    STG_FIT_INSERT,
    STG_FIT_SET_JOB,
    STG_FIT_GET,
    STG_FIT_COUNT,
    STG_FIT_LIST,
    STG_FIT_MAP_INSERT,
    STG_FIT_MAP_GET,
    STG_CALIB_CURRENT_ID,
    STG_CALIB_NEXT_ID,
    STG_CALIB_SUPERSEDE,
    STG_CALIB_INSERT,
    STG_CALIB_GET,
    STG_CALIB_CURRENT,
    STG_CALIB_HISTORY,
    STG_CALIB_COUNT,
    STG_CALIB_SEARCH,
    STG_SCAN_RESUME,
    STG_JOB_RESUME,
    STG_PTC_INSERT,
    STG_PTC_HISTORY,
    STG_PTC_GET,
    STG_N
};

/* Column lists of the SELECTs whose rows the row readers (read_* of each file) decode, in order. */
#define STG_SENSOR_COLS                                                                           \
    "id, model, serial, n_cols, n_rows, pitch_um, gain_e_per_dn, read_noise_e, bias_dn, "         \
    "full_scale_dn, created_ms"
#define STG_SCAN_COLS                                                                             \
    "id, sensor_id, poi_col, poi_row, wavelength_um, na, spot_radius_um, area_px, step_um, "      \
    "sub_px, frames, exposure_us, points_total, state, points_done, error, created_ms, "          \
    "started_ms, finished_ms"
/* after STG_SCAN_COLS in the scan list: the params of the scan's newest scan job (NULL: none) */
#define STG_SCAN_JOB_PARAMS                                                                       \
    "(SELECT j.params FROM jobs j WHERE j.scan_id = scans.id AND j.kind = 'scan' "               \
    "ORDER BY j.id DESC LIMIT 1)"
/* the last column: a job of every pixel ("pixels" a string) gets its fits (schema 6: fits.job_id)
 * as a JSON array in id order, the order stored ('[]' before the first; NULL for other jobs).
 * A window, not a plain aggregate: only its ORDER BY makes json_group_array's order certain. */
#define STG_JOB_COLS                                                                              \
    "id, kind, params, state, progress, points_done, error, attempts, heartbeat_ms, created_ms, " \
    "started_ms, finished_ms, scan_id, fit_id, "                                                  \
    "CASE WHEN json_type(params, '$.pixels') = 'text' THEN coalesce((SELECT "                     \
    "json_group_array(f.id) OVER (ORDER BY f.id ROWS BETWEEN UNBOUNDED PRECEDING AND "            \
    "UNBOUNDED FOLLOWING) FROM fits f WHERE f.job_id = jobs.id LIMIT 1), '[]') END, "             \
    "bench, claimed_by"
#define STG_FIT_COLS                                                                              \
    "f.id, f.scan_id, f.dcol, f.drow, f.noise_model, f.best_r_aic, f.best_r_bic, f.f_value, "     \
    "f.p_value, f.result, f.created_ms, m.sensor_id, m.pixel_col, m.pixel_row, m.r, c.id, "       \
    "c.fit_id, m.map"
/* the map a fit offers, read as a calibration (storage_fit.c, stg_fit_map_load) */
#define STG_FIT_MAP_COLS                                                                          \
    "m.fit_id, m.sensor_id, m.pixel_col, m.pixel_row, m.r, m.s, m.s_err, m.i0, m.chi2_red, "      \
    "m.status, f.scan_id, f.noise_model, m.wavelength_um, m.na, m.spot_radius_um, "               \
    "m.software_version, m.map, m.s_res, m.map_note"
#define STG_CALIB_COLS                                                                            \
    "c.id, c.sensor_id, c.pixel_col, c.pixel_row, c.r, c.s, c.s_err, c.i0, c.chi2_red, "          \
    "c.status, c.scan_id, c.fit_id, c.noise_model, c.wavelength_um, c.na, c.spot_radius_um, "     \
    "c.software_version, c.created_ms, c.superseded_by, c.supersedes, c.changed_by, c.reason, "   \
    "c.map, c.s_res, c.map_note"

#define STG_PTC_COLS                                                                              \
    "id, sensor_id, gain_e_per_dn, read_noise_e, dark_dn, saturation_dn, linearity_error_pct, "   \
    "result, job_id, created_ms"

extern const char *const stg_sql[STG_N];
/* stg_migrations[i] brings user_version i to i + 1 and ends by setting it. */
extern const char *const stg_migrations[];
extern const int stg_n_migrations;

struct storage {
    sqldb_t *db;
    sqldb_stmt_t *stmt[STG_N];
    storage_clock_fn clock;
    void *clock_ctx;
    storage_gate_t *gate; /* shared with the process's other handles, or NULL (storage_gate.c) */
    int gate_held;        /* this handle is in a write transaction through the gate */
    int calib_dirty;      /* this write transaction stored a calibration (storage_gate.c) */
    int64_t changes_at_begin; /* sqldb_total_changes when it began */
    char *claimant; /* the ipsd this handle works for (storage_set_claimant), NULL unnamed */
};

/* storage_listen.c: the thread that LISTENs for other instances' calibrations on a shared
 * PostgreSQL database and moves the gate's calibration generation *gen for each. */
struct stg_listener;
int stg_listener_start(atomic_uint_least64_t *gen, const char *uri, const char *own_token,
                       struct stg_listener **out, err_t *err);
int stg_listener_listening(const struct stg_listener *l);
void stg_listener_stop(struct stg_listener *l);

/* The write gate around BEGIN IMMEDIATE .. COMMIT / ROLLBACK (no-ops without a gate): enter
 * returns 0 or -EDEADLK when this thread holds the gate through another handle. */
int stg_gate_enter(storage_t *st);
void stg_gate_leave(storage_t *st);
/* A calibration stored in the open write transaction: the gate's calibration generation turns
 * odd (storage_calib_generation answers -EBUSY: no caching) until it ends. */
void stg_gate_calib_written(storage_t *st);
/* After COMMIT succeeded: counts a calibration change when the transaction stored one (the
 * generation even again). */
void stg_gate_committed(storage_t *st);
/* The NOTIFY a transaction of this gate's handles sends when it stores a calibration on a shared
 * PostgreSQL database: its payload is the gate's token, which the gate's own listener ignores
 * (stg_gate_committed has counted the change already; hearing it again, late, would empty the
 * reply cache once more for nothing). */
const char *stg_gate_notify_sql(const storage_gate_t *g);
/* The gate's health (storage.h): a storage fault (code -ENOSPC, -EROFS or -EIO, message msg;
 * for -ENOSPC the database's pages and free pages then, -1 unknown), or a write that committed.
 * No-ops without a gate. */
void stg_gate_fault(storage_t *st, int code, const char *msg, int64_t pages, int64_t free_pages);
void stg_gate_ok(storage_t *st);
/* 1 when the current fault is "full", with the pages and free pages recorded at it; else 0. */
int stg_gate_full(storage_t *st, int64_t *pages, int64_t *free_pages);
/* The test hook's injected fault for a write beginning now: an SQLite result code, SQLDB_OK for
 * none (storage_gate_set_test_faults). */
int stg_gate_injected(storage_t *st);

/* The cached statement id, prepared on first use; 0 or -EIO/-ENOMEM. Give it back with
 * stg_reset once its rows are read (before the next use or the end of the transaction). */
int stg_stmt(storage_t *st, enum stg_id id, sqldb_stmt_t **out, err_t *err);
void stg_reset(sqldb_stmt_t *s);

/* Maps a driver result code to a negative errno and sets "what: the database's words" in err. */
int stg_error(storage_t *st, int rc, err_t *err, const char *what);

/* Binders: do nothing when *rc is already an error, else bind and store the result in *rc.
 * bind_double binds NULL for NaN; bind_id binds NULL for 0; bind_text binds NULL for NULL. */
void stg_bind_int(sqldb_stmt_t *s, int i, int64_t v, int *rc);
void stg_bind_id(sqldb_stmt_t *s, int i, int64_t v, int *rc);
void stg_bind_double(sqldb_stmt_t *s, int i, double v, int *rc);
void stg_bind_text(sqldb_stmt_t *s, int i, const char *v, int *rc);
void stg_bind_blob(sqldb_stmt_t *s, int i, const void *v, size_t n, int *rc);
/* Binds the map columns that calibrations and fit_maps share, ?2..?10 in this order: sensor_id,
 * pixel_col, pixel_row, r, s, s_err, i0, chi2_red, status. The two BLOBs are encoded into *s and
 * *e, which must live until the statement has run (caller frees both, also on error); -ENOMEM
 * when they cannot be made. */
int stg_bind_map(sqldb_stmt_t *q, const storage_calib_t *c, unsigned char **s, unsigned char **e,
                 int *rc);

/* Column readers: NULL reads as NaN (double), 0 (id), NULL (text). stg_col_text returns a
 * malloc'ed copy and sets *oom when the copy fails. */
double stg_col_double(sqldb_stmt_t *s, int i);
int64_t stg_col_id(sqldb_stmt_t *s, int i);
char *stg_col_text(sqldb_stmt_t *s, int i, int *oom);
/* The map column i names (storage_map_t; a word the schema's CHECK lets in, else recommended). */
storage_map_t stg_col_map(sqldb_stmt_t *s, int i);
/* Binds ?i to the r*r float64 BLOB of v, or NULL when v is NULL; *buf (caller frees, also on
 * error) must live until the statement has run. -ENOMEM when the BLOB cannot be made. */
int stg_bind_f64_or_null(sqldb_stmt_t *q, int i, const double *v, size_t n, unsigned char **buf,
                         int *rc);
/* Column i as n doubles (malloc'ed), NULL for SQL NULL; *bad = 1 for a BLOB of the wrong size,
 * *oom = 1 when out of memory. */
double *stg_col_f64_or_null(sqldb_stmt_t *s, int i, size_t n, int *bad, int *oom);

/* Runs a bound statement that returns no rows and resets it: 0 or a negative errno. */
int stg_run(storage_t *st, sqldb_stmt_t *s, err_t *err, const char *what);
/* stg_run of statement id with ids ?1 = a and ?2 = b (0: NULL). */
int stg_run_ids(storage_t *st, enum stg_id id, int64_t a, int64_t b, err_t *err,
                const char *what);
/* Steps a bound statement expecting one row: 0 (row ready), -ENOENT (no row), or an error. */
int stg_row(storage_t *st, sqldb_stmt_t *s, err_t *err, const char *what);

/* Steps a bound COUNT statement (rc: the binding result) into *total and resets it. */
int stg_count(storage_t *st, sqldb_stmt_t *s, int rc, int64_t *total, err_t *err,
              const char *what);
/* Reads every row of a bound statement into a growing array of `size`-byte items with read
 * (0, -ENOMEM, or -EIO for a corrupt row; it frees its item on failure), then resets it.
 * *items / *n hold what was read even on failure, for the caller's list_free. */
typedef int (*stg_reader_fn)(sqldb_stmt_t *s, void *item);
int stg_collect(storage_t *st, sqldb_stmt_t *s, size_t size, stg_reader_fn read, void **items,
                size_t *n, err_t *err, const char *what);

/* Transactions: BEGIN IMMEDIATE for writes, BEGIN (deferred) for consistent multi-statement
 * reads; commit rolls back when it fails; rollback is a no-op outside a transaction. */
int stg_begin_write(storage_t *st, err_t *err);
int stg_begin_read(storage_t *st, err_t *err);
int stg_commit(storage_t *st, err_t *err);
void stg_rollback(storage_t *st);

/* Little-endian BLOB codecs (docs/schema.md). Encoders return a malloc'ed buffer (NULL when out of
 * memory); decoders check the byte count and return a malloc'ed array, or NULL (*bad = 1 when the
 * size is wrong, 0 when out of memory). */
unsigned char *stg_blob_from_f64(const double *v, size_t n);
unsigned char *stg_blob_from_u16(const uint16_t *v, size_t n);
double *stg_f64_from_blob(const void *blob, size_t bytes, size_t n, int *bad);
uint16_t *stg_u16_from_blob(const void *blob, size_t bytes, size_t n, int *bad);

/* ---- steps of the per-table files, run inside the caller's transaction (docs/schema.md) ---- */

/* storage_scan.c */
/* Validation shared by the files; each returns 0 or -EINVAL naming the field. */
int stg_check_scan(const storage_scan_t *sc, const storage_sensor_t *sensor, err_t *err);
/* Inserts a scan inside the caller's write transaction (-ENOENT: unknown sensor). */
int stg_scan_insert(storage_t *st, const storage_scan_t *sc, int64_t *id, err_t *err);
/* Reads the scan inside the caller's transaction (-ENOENT when unknown). */
int stg_scan_load(storage_t *st, int64_t id, storage_scan_t *out, err_t *err);
/* Counts one more stored point (the frame's write transaction, storage_frame.c). */
int stg_scan_add_point(storage_t *st, int64_t id, err_t *err);
/* Queues a failed scan again (storage_scan_resume): -ESTALE when it is not failed. */
int stg_scan_resume(storage_t *st, int64_t id, err_t *err);
/* Cancels a queued or running scan (its job's cancel transaction, storage_job.c). */
int stg_scan_cancel(storage_t *st, int64_t id, err_t *err);

/* storage_job.c */
/* Inserts a job inside the caller's write transaction. */
int stg_job_insert(storage_t *st, storage_job_kind_t kind, const char *params_json,
                   int64_t scan_id, int64_t *id, err_t *err);
/* Queues the failed latest scan job of scan_id again, keeping its progress (*job_id: it);
 * -ESTALE when that job is not failed. Inside the caller's write transaction. */
int stg_job_resume(storage_t *st, int64_t scan_id, int64_t *job_id, err_t *err);
/* Records the fit a job produced, inside the caller's write transaction (-ENOENT: no job). */
int stg_job_set_fit(storage_t *st, int64_t job_id, int64_t fit_id, err_t *err);
/* A running job's done units go from `from` to from + 1 (progress: the fraction): -ESTALE when
 * its count is not `from` (that unit is stored already), else as not_running. */
int stg_job_step(storage_t *st, int64_t id, int from, double progress, err_t *err);
/* How many jobs of kind the scan has (any state), inside the caller's transaction. */
int stg_job_count(storage_t *st, storage_job_kind_t kind, int64_t scan_id, int64_t *n, err_t *err);
/* storage_job_finish's statement, inside the caller's transaction (or alone). */
int stg_job_finish(storage_t *st, int64_t id, storage_state_t state, const char *error,
                   err_t *err);

/* storage_fit.c: checks a fit (its pixel inside the scan's sub-frame) and inserts it, inside the
 * caller's write transaction. */
int stg_fit_insert(storage_t *st, const storage_fit_t *f, int64_t *id, err_t *err);
/* Records the job that stored fit_id (fits.job_id, schema 6), inside the caller's transaction. */
int stg_fit_set_job(storage_t *st, int64_t fit_id, int64_t job_id, err_t *err);
/* Keeps c (its pixel, map and optics; checked by the caller) as the map fit_id offers. */
int stg_fit_map_insert(storage_t *st, int64_t fit_id, const storage_calib_t *c, err_t *err);
/* The map fit_id offers, as a calibration (fit_id, scan_id and noise_model from the fit; the
 * provenance fields left zero): -ENOENT for an unknown fit, -ENODATA when it offers none. */
int stg_fit_map_load(storage_t *st, int64_t fit_id, storage_calib_t *out, err_t *err);

/* storage_calib.c: checks a calibration, supersedes the pixel's current one and inserts it,
 * inside the caller's write transaction. */
int stg_calib_insert(storage_t *st, const storage_calib_t *c, int64_t *id, err_t *err);
/* Checks a calibration before it is stored (sensor, pixel, map, by and reason). */
int stg_calib_check(storage_t *st, const storage_calib_t *c, err_t *err);
/* The current calibration of a pixel and the fit it came from (0, 0: none). */
int stg_calib_current_ids(storage_t *st, int64_t sensor_id, int pixel_col, int pixel_row,
                          int64_t *id, int64_t *fit_id, err_t *err);

#endif
