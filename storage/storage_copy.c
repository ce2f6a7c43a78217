/* storage_copy.c: a bench's database copied into another (ipsd --db-copy FROM TO: an SQLite file
 * into the lab's PostgreSQL database, storage.h storage_copy). Rows get the target's ids; each
 * copied row is recorded in the target's copied_rows under the source's own id (database_info,
 * schema 12), so a second run of the same copy skips what is there and copies only what is new.
 * Order follows the foreign keys: sensors (one of the same model and serial already there is the
 * same sensor), scans with their frames and frame times, jobs, fits with the map each offers, the
 * jobs' fit ids, photon-transfer measurements, calibrations. Each unit (a sensor, a scan with all
 * its points, a job, a fit, a pixel's calibration history) is one write transaction of the
 * target, with its copied_rows rows: a copy that stops midway leaves whole units, and goes on from
 * there when run again. A pixel that has a current calibration in the target already keeps one
 * current map: the newer of the two (created_ms), the older superseded by it. */
#include "storage_int.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A column: its name, how it is read and bound ('i' integer, 'f' real, 't' text, 'b' BLOB), and
 * the table its id refers to (mapped through copied_rows), or NULL. */
typedef struct {
    const char *name;
    char type;
    const char *ref;
} col_t;

typedef struct {
    const char *table;
    const col_t *cols;
    int n;
} table_t;

#define N(a) ((int)(sizeof a / sizeof *a))

static const col_t sensor_cols[] = {
    {"model", 't', NULL},         {"serial", 't', NULL},         {"n_cols", 'i', NULL},
    {"n_rows", 'i', NULL},        {"pitch_um", 'f', NULL},       {"gain_e_per_dn", 'f', NULL},
    {"read_noise_e", 'f', NULL},  {"bias_dn", 'f', NULL},        {"full_scale_dn", 'f', NULL},
    {"created_ms", 'i', NULL}};
static const col_t scan_cols[] = {
    {"sensor_id", 'i', "sensors"}, {"poi_col", 'i', NULL},      {"poi_row", 'i', NULL},
    {"wavelength_um", 'f', NULL},  {"na", 'f', NULL},           {"spot_radius_um", 'f', NULL},
    {"area_px", 'i', NULL},        {"step_um", 'f', NULL},      {"sub_px", 'i', NULL},
    {"frames", 'i', NULL},         {"exposure_us", 'f', NULL},  {"points_total", 'i', NULL},
    {"state", 't', NULL},          {"points_done", 'i', NULL},  {"error", 't', NULL},
    {"created_ms", 'i', NULL},     {"started_ms", 'i', NULL},   {"finished_ms", 'i', NULL},
    {"setup", 't', NULL}};
static const col_t frame_cols[] = {
    {"scan_id", 'i', "scans"},    {"point_index", 'i', NULL}, {"stage_x_um", 'f', NULL},
    {"stage_y_um", 'f', NULL},    {"stage_z_um", 'f', NULL},  {"exposure_us", 'f', NULL},
    {"captured_ms", 'i', NULL},   {"mean", 'b', NULL},        {"raw", 'b', NULL}};
static const col_t frame_time_cols[] = {{"scan_id", 'i', "scans"},
                                        {"point_index", 'i', NULL},
                                        {"timestamps_ns", 'b', NULL},
                                        {"camera_frame_ids", 'b', NULL}};
static const col_t job_cols[] = {
    {"kind", 't', NULL},         {"params", 't', NULL},     {"state", 't', NULL},
    {"progress", 'f', NULL},     {"points_done", 'i', NULL}, {"error", 't', NULL},
    {"attempts", 'i', NULL},     {"heartbeat_ms", 'i', NULL}, {"created_ms", 'i', NULL},
    {"started_ms", 'i', NULL},   {"finished_ms", 'i', NULL}, {"scan_id", 'i', "scans"},
    {"bench", 't', NULL},        {"claimed_by", 't', NULL}};
static const col_t fit_cols[] = {
    {"scan_id", 'i', "scans"},  {"dcol", 'i', NULL},       {"drow", 'i', NULL},
    {"noise_model", 't', NULL}, {"best_r_aic", 'i', NULL}, {"best_r_bic", 'i', NULL},
    {"f_value", 'f', NULL},     {"p_value", 'f', NULL},    {"result", 't', NULL},
    {"created_ms", 'i', NULL},  {"job_id", 'i', "jobs"}};
static const col_t fit_map_cols[] = {
    {"fit_id", 'i', "fits"},     {"sensor_id", 'i', "sensors"}, {"pixel_col", 'i', NULL},
    {"pixel_row", 'i', NULL},    {"r", 'i', NULL},              {"s", 'b', NULL},
    {"s_err", 'b', NULL},        {"i0", 'f', NULL},             {"chi2_red", 'f', NULL},
    {"status", 't', NULL},       {"wavelength_um", 'f', NULL},  {"na", 'f', NULL},
    {"spot_radius_um", 'f', NULL}, {"software_version", 't', NULL}, {"map", 't', NULL},
    {"s_res", 'b', NULL},        {"map_note", 't', NULL}};
static const col_t ptc_cols[] = {
    {"sensor_id", 'i', "sensors"}, {"gain_e_per_dn", 'f', NULL}, {"read_noise_e", 'f', NULL},
    {"dark_dn", 'f', NULL},        {"saturation_dn", 'f', NULL}, {"linearity_error_pct", 'f', NULL},
    {"result", 't', NULL},         {"job_id", 'i', "jobs"},      {"created_ms", 'i', NULL}};
/* superseded_by and supersedes are mapped by the pixel's copy (copy_pixel), not here */
static const col_t calib_cols[] = {
    {"sensor_id", 'i', "sensors"}, {"pixel_col", 'i', NULL},     {"pixel_row", 'i', NULL},
    {"r", 'i', NULL},              {"s", 'b', NULL},             {"s_err", 'b', NULL},
    {"i0", 'f', NULL},             {"chi2_red", 'f', NULL},      {"status", 't', NULL},
    {"scan_id", 'i', "scans"},     {"fit_id", 'i', "fits"},      {"noise_model", 't', NULL},
    {"wavelength_um", 'f', NULL},  {"na", 'f', NULL},            {"spot_radius_um", 'f', NULL},
    {"software_version", 't', NULL}, {"created_ms", 'i', NULL},  {"changed_by", 't', NULL},
    {"reason", 't', NULL},         {"map", 't', NULL},           {"s_res", 'b', NULL},
    {"map_note", 't', NULL},       {"id", 'i', NULL},            {"superseded_by", 'i', NULL},
    {"supersedes", 'i', NULL}};

static const table_t T_SENSORS = {"sensors", sensor_cols, N(sensor_cols)};
static const table_t T_SCANS = {"scans", scan_cols, N(scan_cols)};
static const table_t T_FRAMES = {"frames", frame_cols, N(frame_cols)};
static const table_t T_FRAME_TIMES = {"frame_times", frame_time_cols, N(frame_time_cols)};
static const table_t T_JOBS = {"jobs", job_cols, N(job_cols)};
static const table_t T_FITS = {"fits", fit_cols, N(fit_cols)};
static const table_t T_FIT_MAPS = {"fit_maps", fit_map_cols, N(fit_map_cols)};
static const table_t T_PTC = {"ptc", ptc_cols, N(ptc_cols)};
static const table_t T_CALIBS = {"calibrations", calib_cols, N(calib_cols)};

typedef struct {
    storage_t *from, *to;
    const char *bench; /* the bench the copied scan and ptc jobs without one belong to */
    char origin[40];
    storage_copy_info_t *info;
    err_t *err;
} copy_t;

/* ---- statements built from the specs (names are the code's constants, values bound) -------- */

static int prepare(storage_t *st, const char *sql, sqldb_stmt_t **out, err_t *err)
{
    int rc = sqldb_prepare(st->db, sql, 0, out);
    return rc == SQLDB_OK ? 0 : stg_error(st, rc, err, "preparing the copy's statement");
}

/* "SELECT id, cols FROM table WHERE where ORDER BY order" into sql (where may be ""). */
static void select_sql(const table_t *t, const char *first, const char *where, const char *order,
                       char *sql, size_t n)
{
    size_t k = (size_t)snprintf(sql, n, "SELECT %s", first);
    for (int i = 0; i < t->n; i++) k += (size_t)snprintf(sql + k, n - k, ", %s", t->cols[i].name);
    snprintf(sql + k, n - k, " FROM %s%s%s ORDER BY %s", t->table, *where ? " WHERE " : "", where,
             order);
}

/* "INSERT INTO table (cols) VALUES (?1..?n)" and " RETURNING id" when returning. */
static void insert_sql(const table_t *t, int n_cols, int returning, char *sql, size_t n)
{
    size_t k = (size_t)snprintf(sql, n, "INSERT INTO %s (", t->table);
    for (int i = 0; i < n_cols; i++)
        k += (size_t)snprintf(sql + k, n - k, "%s%s", i ? ", " : "", t->cols[i].name);
    k += (size_t)snprintf(sql + k, n - k, ") VALUES (");
    for (int i = 0; i < n_cols; i++) k += (size_t)snprintf(sql + k, n - k, "%s?%d", i ? ", " : "", i + 1);
    snprintf(sql + k, n - k, ")%s", returning ? " RETURNING id" : "");
}

/* ---- the map of copied rows ----------------------------------------------------------------- */

/* The target's id of source row src of table (0: not copied yet). */
static int mapped(copy_t *c, const char *table, int64_t src, int64_t *dst)
{
    sqldb_stmt_t *q;
    *dst = 0;
    int ret = prepare(c->to,
                      "SELECT target_id FROM copied_rows WHERE origin = ?1 AND tbl = ?2 "
                      "AND source_id = ?3",
                      &q, c->err);
    if (ret) return ret;
    int rc = SQLDB_OK;
    stg_bind_text(q, 1, c->origin, &rc);
    stg_bind_text(q, 2, table, &rc);
    stg_bind_int(q, 3, src, &rc);
    if (rc == SQLDB_OK) rc = sqldb_step(q);
    if (rc == SQLDB_ROW) *dst = sqldb_col_int64(q, 0);
    else if (rc != SQLDB_DONE) ret = stg_error(c->to, rc, c->err, "reading the copied rows");
    sqldb_finalize(q);
    return ret;
}

static int record(copy_t *c, const char *table, int64_t src, int64_t dst)
{
    sqldb_stmt_t *q;
    int ret = prepare(c->to,
                      "INSERT INTO copied_rows (origin, tbl, source_id, target_id) "
                      "VALUES (?1, ?2, ?3, ?4)",
                      &q, c->err);
    if (ret) return ret;
    int rc = SQLDB_OK;
    stg_bind_text(q, 1, c->origin, &rc);
    stg_bind_text(q, 2, table, &rc);
    stg_bind_int(q, 3, src, &rc);
    stg_bind_int(q, 4, dst, &rc);
    ret = rc == SQLDB_OK ? stg_run(c->to, q, c->err, "recording a copied row")
                         : stg_error(c->to, rc, c->err, "recording a copied row");
    sqldb_finalize(q);
    return ret;
}

/* Runs an UPDATE of the target with ?1 = id and ?2 = text when text, else v. */
static int update(copy_t *c, const char *sql, int64_t id, int64_t v, const char *text,
                  const char *what)
{
    sqldb_stmt_t *q;
    int ret = prepare(c->to, sql, &q, c->err), rc = SQLDB_OK;
    if (ret) return ret;
    stg_bind_int(q, 1, id, &rc);
    if (text) stg_bind_text(q, 2, text, &rc);
    else stg_bind_int(q, 2, v, &rc);
    ret = rc == SQLDB_OK ? stg_run(c->to, q, c->err, what) : stg_error(c->to, rc, c->err, what);
    sqldb_finalize(q);
    return ret;
}

/* ---- one row ----------------------------------------------------------------------------- */

/* Binds the first n columns of source row s (its column 0 is the id, then the spec's) to q,
 * mapping references; -EIO when a reference was not copied (the order above prevents it). */
static int bind_row(copy_t *c, const table_t *t, int n, sqldb_stmt_t *s, sqldb_stmt_t *q)
{
    int rc = SQLDB_OK, ret = 0;
    for (int i = 0; i < n && rc == SQLDB_OK && !ret; i++) {
        const col_t *col = &t->cols[i];
        int k = i + 1;
        if (sqldb_col_null(s, k)) {
            rc = sqldb_bind_null(q, i + 1);
        } else if (col->ref) {
            int64_t dst = 0;
            if ((ret = mapped(c, col->ref, sqldb_col_int64(s, k), &dst))) break;
            if (!dst)
                ret = err_set(c->err, -EIO, "copy: %s row %lld refers to %s %lld, not copied",
                              t->table, (long long)sqldb_col_int64(s, 0), col->ref,
                              (long long)sqldb_col_int64(s, k));
            else
                rc = sqldb_bind_int64(q, i + 1, dst);
        } else if (col->type == 'i') {
            rc = sqldb_bind_int64(q, i + 1, sqldb_col_int64(s, k));
        } else if (col->type == 'f') {
            rc = sqldb_bind_double(q, i + 1, sqldb_col_double(s, k));
        } else if (col->type == 't') {
            rc = sqldb_bind_text(q, i + 1, sqldb_col_text(s, k));
        } else {
            rc = sqldb_bind_blob(q, i + 1, sqldb_col_blob(s, k), sqldb_col_bytes(s, k));
        }
    }
    return ret ? ret : rc == SQLDB_OK ? 0 : stg_error(c->to, rc, c->err, "copy: binding a row");
}

/* Inserts the current row s of table t into the target (its first n columns); *id: the new
 * row's id (0 for a table without one). */
static int insert_row(copy_t *c, const table_t *t, int n, sqldb_stmt_t *s, int returning,
                      int64_t *id)
{
    char sql[2048];
    sqldb_stmt_t *q;
    insert_sql(t, n, returning, sql, sizeof sql);
    int ret = prepare(c->to, sql, &q, c->err);
    if (ret) return ret;
    if (!(ret = bind_row(c, t, n, s, q))) {
        int rc = sqldb_step(q);
        if (returning && rc == SQLDB_ROW) {
            *id = sqldb_col_int64(q, 0);
            rc = sqldb_step(q);
        }
        if (rc != SQLDB_DONE) ret = stg_error(c->to, rc, c->err, "copy: inserting a row");
    }
    sqldb_finalize(q);
    if (ret == -EINVAL || ret == -EEXIST || ret == -ENOENT) {
        err_t why = *c->err;
        ret = err_set(c->err, ret, "copy: %s row %lld: %s", t->table,
                      (long long)sqldb_col_int64(s, 0), why.msg);
    }
    return ret;
}

/* Every row of the source's table t matching where (bound: ?1 = arg when arg), id order, each
 * inserted into the target under the target's references (no copied_rows: its unit records). */
static int copy_children(copy_t *c, const table_t *t, const char *first, const char *where,
                         int64_t arg, int64_t *count)
{
    char sql[2048];
    sqldb_stmt_t *s;
    select_sql(t, first, where, first, sql, sizeof sql);
    int ret = prepare(c->from, sql, &s, c->err), rc = SQLDB_OK;
    if (ret) return ret;
    if (*where) rc = sqldb_bind_int64(s, 1, arg);
    int64_t id;
    while (rc == SQLDB_OK && !ret && (rc = sqldb_step(s)) == SQLDB_ROW) {
        ret = insert_row(c, t, t->n, s, 0, &id);
        (*count)++;
        rc = SQLDB_OK;
    }
    if (!ret && rc != SQLDB_DONE) ret = stg_error(c->from, rc, c->err, "copy: reading the source");
    sqldb_finalize(s);
    return ret;
}

/* ---- the units ------------------------------------------------------------------------------ */

/* The target's sensor of the same model and serial (0: none). */
static int same_sensor(copy_t *c, sqldb_stmt_t *s, int64_t *id)
{
    sqldb_stmt_t *q;
    *id = 0;
    int ret = prepare(c->to, "SELECT id FROM sensors WHERE model = ?1 AND serial = ?2", &q, c->err);
    if (ret) return ret;
    int rc = sqldb_bind_text(q, 1, sqldb_col_text(s, 1));
    if (rc == SQLDB_OK) rc = sqldb_bind_text(q, 2, sqldb_col_text(s, 2));
    if (rc == SQLDB_OK) rc = sqldb_step(q);
    if (rc == SQLDB_ROW) *id = sqldb_col_int64(q, 0);
    else if (rc != SQLDB_DONE) ret = stg_error(c->to, rc, c->err, "copy: finding a sensor");
    sqldb_finalize(q);
    return ret;
}

/* One unit (source row s of t) in one target transaction: skipped when copied already, else
 * inserted (with extra's rows: a scan's frames, a fit's map) and recorded. */
static int copy_unit(copy_t *c, const table_t *t, sqldb_stmt_t *s, int64_t *count)
{
    int64_t src = sqldb_col_int64(s, 0), dst = 0;
    int ret = stg_begin_write(c->to, c->err);
    if (ret) return ret;
    if ((ret = mapped(c, t->table, src, &dst)) || dst) {
        if (dst) c->info->skipped++;
        goto out;
    }
    if (t == &T_SENSORS && !(ret = same_sensor(c, s, &dst)) && dst) {
        c->info->sensors_matched++;
    } else if (!ret && !(ret = insert_row(c, t, t->n, s, 1, &dst))) {
        (*count)++;
    }
    if (!ret) ret = record(c, t->table, src, dst);
    if (!ret && t == &T_SCANS)
        ret = copy_children(c, &T_FRAMES, "point_index", "scan_id = ?1", src, &c->info->frames);
    if (!ret && t == &T_SCANS) {
        int64_t n = 0;
        ret = copy_children(c, &T_FRAME_TIMES, "point_index", "scan_id = ?1", src, &n);
    }
    if (!ret && t == &T_FITS) {
        int64_t n = 0;
        ret = copy_children(c, &T_FIT_MAPS, "fit_id", "fit_id = ?1", src, &n);
    }
    if (!ret && t == &T_JOBS && c->bench) /* an SQLite file's jobs name no bench */
        ret = update(c, "UPDATE jobs SET bench = ?2 WHERE id = ?1 AND bench IS NULL AND "
                        "kind <> 'fit'",
                     dst, 0, c->bench, "copy: a job's bench");
out:
    if (ret) {
        stg_rollback(c->to);
        return ret;
    }
    return stg_commit(c->to, c->err);
}

static int copy_table(copy_t *c, const table_t *t, int64_t *count)
{
    char sql[2048];
    sqldb_stmt_t *s;
    select_sql(t, "id", "", "id", sql, sizeof sql);
    int ret = prepare(c->from, sql, &s, c->err), rc = SQLDB_OK;
    if (ret) return ret;
    while (!ret && (rc = sqldb_step(s)) == SQLDB_ROW) ret = copy_unit(c, t, s, count);
    if (!ret && rc != SQLDB_DONE) ret = stg_error(c->from, rc, c->err, "copy: reading the source");
    sqldb_finalize(s);
    return ret;
}

/* The jobs' fit ids (a job refers to the fit it produced, a fit to its job: the jobs went in
 * first, without theirs). */
static int link_jobs_to_fits(copy_t *c)
{
    sqldb_stmt_t *s;
    int ret = prepare(c->from, "SELECT id, fit_id FROM jobs WHERE fit_id IS NOT NULL ORDER BY id",
                      &s, c->err);
    if (ret) return ret;
    if ((ret = stg_begin_write(c->to, c->err))) {
        sqldb_finalize(s);
        return ret;
    }
    int rc = SQLDB_OK;
    while (!ret && (rc = sqldb_step(s)) == SQLDB_ROW) {
        int64_t job = 0, fit = 0;
        if ((ret = mapped(c, "jobs", sqldb_col_int64(s, 0), &job)) ||
            (ret = mapped(c, "fits", sqldb_col_int64(s, 1), &fit)) || !job || !fit)
            continue;
        ret = update(c, "UPDATE jobs SET fit_id = ?2 WHERE id = ?1 AND fit_id IS NULL", job, fit,
                     NULL, "copy: a job's fit");
    }
    sqldb_finalize(s);
    if (ret) {
        stg_rollback(c->to);
        return ret;
    }
    return stg_commit(c->to, c->err);
}

/* One pixel's calibration history (source rows of sensor, col, row not copied yet), in one target
 * transaction: new ids allocated first (superseded_by points forward), the references between
 * the pixel's rows mapped through them, and one current map kept (the newer). */
static int copy_pixel(copy_t *c, int64_t sensor, int64_t col, int64_t row)
{
    char sql[2048];
    sqldb_stmt_t *s = NULL, *q = NULL;
    int64_t *src = NULL, *dst = NULL, n = 0, cap = 0, next = 0, tsensor = 0;
    int ret = stg_begin_write(c->to, c->err), rc = SQLDB_OK;
    if (ret) return ret;
    if ((ret = mapped(c, "sensors", sensor, &tsensor))) goto out;
    /* the ids the new rows get: after the target's largest (the write lock is held) */
    if ((ret = prepare(c->to, "SELECT coalesce(max(id), 0) FROM calibrations", &q, c->err)))
        goto out;
    if ((rc = sqldb_step(q)) == SQLDB_ROW) next = sqldb_col_int64(q, 0);
    sqldb_finalize(q);
    q = NULL;
    if (rc != SQLDB_ROW) {
        ret = stg_error(c->to, rc, c->err, "copy: the calibrations' next id");
        goto out;
    }
    rc = SQLDB_OK;
    select_sql(&T_CALIBS, "id",
               "sensor_id = ?1 AND pixel_col = ?2 AND pixel_row = ?3", "id", sql, sizeof sql);
    if ((ret = prepare(c->from, sql, &s, c->err))) goto out;
    stg_bind_int(s, 1, sensor, &rc);
    stg_bind_int(s, 2, col, &rc);
    stg_bind_int(s, 3, row, &rc);
    while (rc == SQLDB_OK && !ret && (rc = sqldb_step(s)) == SQLDB_ROW) {
        int64_t d = 0;
        if ((ret = mapped(c, "calibrations", sqldb_col_int64(s, 0), &d))) break;
        if (n == cap) {
            cap = cap ? 2 * cap : 16;
            int64_t *a = realloc(src, (size_t)cap * sizeof *a), *b = a ? realloc(dst, (size_t)cap * sizeof *b) : NULL;
            if (a) src = a;
            if (!a || !b) {
                ret = err_set(c->err, -ENOMEM, "copy: out of memory");
                break;
            }
            dst = b;
        }
        src[n] = sqldb_col_int64(s, 0);
        dst[n++] = d ? -d : ++next; /* negative: copied before (kept as it is) */
        rc = SQLDB_OK;
    }
    sqldb_finalize(s);
    s = NULL;
    if (ret || (rc != SQLDB_OK && rc != SQLDB_DONE)) {
        if (!ret) ret = stg_error(c->from, rc, c->err, "copy: reading the source's calibrations");
        goto out;
    }
    /* the target's current map of the pixel that did not come from here, if any */
    int64_t cur = 0, cur_ms = 0;
    if ((ret = prepare(c->to,
                       "SELECT id, created_ms FROM calibrations WHERE sensor_id = ?1 AND "
                       "pixel_col = ?2 AND pixel_row = ?3 AND superseded_by IS NULL",
                       &q, c->err)))
        goto out;
    rc = SQLDB_OK;
    stg_bind_int(q, 1, tsensor, &rc);
    stg_bind_int(q, 2, col, &rc);
    stg_bind_int(q, 3, row, &rc);
    if (rc == SQLDB_OK && (rc = sqldb_step(q)) == SQLDB_ROW) {
        cur = sqldb_col_int64(q, 0);
        cur_ms = sqldb_col_int64(q, 1);
    }
    sqldb_finalize(q);
    q = NULL;
    for (int64_t i = 0; i < n && cur; i++)
        if (dst[i] == -cur) cur = 0; /* that current map is this origin's own, copied before */
    rc = SQLDB_OK;
    if ((ret = prepare(c->from, sql, &s, c->err))) goto out;
    stg_bind_int(s, 1, sensor, &rc);
    stg_bind_int(s, 2, col, &rc);
    stg_bind_int(s, 3, row, &rc);
    for (int64_t i = 0; rc == SQLDB_OK && !ret && (rc = sqldb_step(s)) == SQLDB_ROW; i++) {
        rc = SQLDB_OK;
        if (dst[i] < 0) continue;
        /* the pixel's own links, through the new ids (or those of an earlier copy) */
        int64_t links[2] = {0, 0};
        for (int l = 0; l < 2; l++) {
            int k = T_CALIBS.n - 1 + l; /* superseded_by, supersedes (1-based: after the id) */
            int64_t v = sqldb_col_null(s, k) ? 0 : sqldb_col_int64(s, k);
            for (int64_t j = 0; v && j < n; j++)
                if (src[j] == v) links[l] = dst[j] < 0 ? -dst[j] : dst[j];
        }
        int current = sqldb_col_null(s, T_CALIBS.n - 1), relink = 0;
        int64_t made_ms = sqldb_col_int64(s, 17);
        if (current && cur) {
            if (cur_ms >= made_ms) { /* the target's is newer: this one becomes history */
                links[0] = cur;
                relink = 1; /* and the target's supersedes it, once it is in */
            } else {          /* this one is newer: the target's is superseded by it */
                if ((ret = update(c, "UPDATE calibrations SET superseded_by = ?2 WHERE id = ?1",
                                  cur, dst[i], NULL, "copy: superseding a map")))
                    break;
                if (!links[1]) links[1] = cur;
            }
        }
        insert_sql(&T_CALIBS, T_CALIBS.n, 0, sql, sizeof sql);
        if ((ret = prepare(c->to, sql, &q, c->err))) break;
        if (!(ret = bind_row(c, &T_CALIBS, T_CALIBS.n - 3, s, q))) {
            int rc2 = sqldb_bind_int64(q, T_CALIBS.n - 2, dst[i]);
            if (rc2 == SQLDB_OK)
                rc2 = links[0] ? sqldb_bind_int64(q, T_CALIBS.n - 1, links[0])
                               : sqldb_bind_null(q, T_CALIBS.n - 1);
            if (rc2 == SQLDB_OK)
                rc2 = links[1] ? sqldb_bind_int64(q, T_CALIBS.n, links[1])
                               : sqldb_bind_null(q, T_CALIBS.n);
            if (rc2 == SQLDB_OK) rc2 = sqldb_step(q);
            if (rc2 != SQLDB_DONE) ret = stg_error(c->to, rc2, c->err, "copy: inserting a map");
        }
        sqldb_finalize(q);
        q = NULL;
        if (!ret && relink)
            ret = update(c, "UPDATE calibrations SET supersedes = ?2 WHERE id = ?1 AND "
                            "supersedes IS NULL",
                         cur, dst[i], NULL, "copy: linking a history");
        if (!ret) ret = record(c, "calibrations", src[i], dst[i]);
        if (!ret) c->info->calibrations++;
    }
    if (!ret && rc != SQLDB_OK && rc != SQLDB_DONE)
        ret = stg_error(c->from, rc, c->err, "copy: reading the source's calibrations");
out:
    sqldb_finalize(s);
    free(src);
    free(dst);
    if (ret) {
        stg_rollback(c->to);
        return ret;
    }
    return stg_commit(c->to, c->err);
}

static int copy_calibrations(copy_t *c)
{
    sqldb_stmt_t *s;
    int ret = prepare(c->from,
                      "SELECT sensor_id, pixel_col, pixel_row FROM calibrations "
                      "GROUP BY sensor_id, pixel_col, pixel_row ORDER BY min(id)",
                      &s, c->err),
        rc = SQLDB_OK;
    if (ret) return ret;
    while (!ret && (rc = sqldb_step(s)) == SQLDB_ROW)
        ret = copy_pixel(c, sqldb_col_int64(s, 0), sqldb_col_int64(s, 1), sqldb_col_int64(s, 2));
    if (!ret && rc != SQLDB_DONE) ret = stg_error(c->from, rc, c->err, "copy: reading the source");
    sqldb_finalize(s);
    return ret;
}

/* A database's own id (database_info). */
static int database_id(storage_t *st, char *out, size_t n, err_t *err)
{
    sqldb_stmt_t *s;
    int ret = prepare(st, "SELECT id FROM database_info", &s, err);
    if (ret) return ret;
    int rc = sqldb_step(s);
    if (rc == SQLDB_ROW && sqldb_col_text(s, 0)) snprintf(out, n, "%s", sqldb_col_text(s, 0));
    else ret = err_set(err, -EIO, "copy: the database has no id (database_info)");
    sqldb_finalize(s);
    return ret;
}

int storage_copy(storage_t *from, storage_t *to, const char *bench, storage_copy_info_t *info,
                 err_t *err)
{
    if (!from || !to || !info) return err_set(err, -EINVAL, "copy: NULL argument");
    memset(info, 0, sizeof *info);
    copy_t c = {.from = from, .to = to, .bench = bench, .info = info, .err = err};
    char target[40];
    int ret = database_id(from, c.origin, sizeof c.origin, err);
    if (!ret) ret = database_id(to, target, sizeof target, err);
    if (!ret && !strcmp(c.origin, target))
        return err_set(err, -EINVAL, "copy: the source and the target are the same database");
    if (ret || (ret = copy_table(&c, &T_SENSORS, &info->sensors)) ||
        (ret = copy_table(&c, &T_SCANS, &info->scans)) ||
        (ret = copy_table(&c, &T_JOBS, &info->jobs)) ||
        (ret = copy_table(&c, &T_FITS, &info->fits)) || (ret = link_jobs_to_fits(&c)) ||
        (ret = copy_table(&c, &T_PTC, &info->ptc)))
        return ret;
    return copy_calibrations(&c);
}
