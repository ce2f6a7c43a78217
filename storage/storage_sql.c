/* storage_sql.c: every SQL text of ipsd: the schema migrations and the statements the code
 * prepares (once per connection). Values are always bound parameters, never spliced into SQL.
 * The schema is documented for people in docs/schema.md: keep the two in step. */
#include "storage_int.h"

/* The columns of fit_maps and calibrations at schema 7, in order (migration 8 copies them). */
#define FIT_MAP_COLUMNS_V7                                                                        \
    "fit_id, sensor_id, pixel_col, pixel_row, r, s, s_err, i0, chi2_red, status, wavelength_um, " \
    "na, spot_radius_um, software_version, map, s_res"
#define CALIBRATION_COLUMNS_V7                                                                    \
    "id, sensor_id, pixel_col, pixel_row, r, s, s_err, i0, chi2_red, status, scan_id, fit_id, "   \
    "noise_model, wavelength_um, na, spot_radius_um, software_version, created_ms, "              \
    "superseded_by, supersedes, changed_by, reason, map, s_res"

/* Migration N (index N-1) brings user_version N-1 to N inside one transaction run by
 * storage_open. Never edit a released migration: add a new one. */
const char *const stg_migrations[] = {
    /* 1: the initial schema */
    "CREATE TABLE sensors (\n"
    "    id            INTEGER PRIMARY KEY,\n"
    "    model         TEXT    NOT NULL CHECK (length(model) > 0),\n"
    "    serial        TEXT    NOT NULL CHECK (length(serial) > 0),\n"
    "    n_cols        INTEGER NOT NULL CHECK (n_cols > 0),\n"
    "    n_rows        INTEGER NOT NULL CHECK (n_rows > 0),\n"
    "    pitch_um      REAL    NOT NULL CHECK (pitch_um > 0),\n"
    "    gain_e_per_dn REAL    NOT NULL CHECK (gain_e_per_dn > 0),\n"
    "    read_noise_e  REAL    NOT NULL CHECK (read_noise_e >= 0),\n"
    "    bias_dn       REAL    NOT NULL,\n"
    "    full_scale_dn REAL    NOT NULL CHECK (full_scale_dn > 0),\n"
    "    created_ms    INTEGER NOT NULL,\n"
    "    UNIQUE (model, serial)\n"
    ");\n"
    "CREATE TABLE scans (\n"
    "    id             INTEGER PRIMARY KEY,\n"
    "    sensor_id      INTEGER NOT NULL REFERENCES sensors (id),\n"
    "    poi_col        INTEGER NOT NULL CHECK (poi_col >= 0),\n"
    "    poi_row        INTEGER NOT NULL CHECK (poi_row >= 0),\n"
    "    wavelength_um  REAL    NOT NULL CHECK (wavelength_um > 0),\n"
    "    na             REAL    NOT NULL CHECK (na > 0),\n"
    "    spot_radius_um REAL    NOT NULL CHECK (spot_radius_um > 0),\n"
    "    area_px        INTEGER NOT NULL CHECK (area_px > 0),\n"
    "    step_um        REAL    NOT NULL CHECK (step_um > 0),\n"
    "    sub_px         INTEGER NOT NULL CHECK (sub_px > 0 AND sub_px % 2 = 1),\n"
    "    frames         INTEGER NOT NULL CHECK (frames > 0),\n"
    "    exposure_us    REAL    NOT NULL CHECK (exposure_us > 0),\n"
    "    points_total   INTEGER NOT NULL CHECK (points_total > 0),\n"
    "    state          TEXT    NOT NULL DEFAULT 'queued'\n"
    "                   CHECK (state IN ('queued', 'running', 'done', 'failed', 'cancelled')),\n"
    "    points_done    INTEGER NOT NULL DEFAULT 0\n"
    "                   CHECK (points_done BETWEEN 0 AND points_total),\n"
    "    error          TEXT,\n"
    "    created_ms     INTEGER NOT NULL,\n"
    "    started_ms     INTEGER,\n"
    "    finished_ms    INTEGER\n"
    ");\n"
    "CREATE INDEX scans_sensor_state ON scans (sensor_id, state);\n"
    /* raw is the last column: reading mean (the raster) never walks raw's overflow pages */
    "CREATE TABLE frames (\n"
    "    id          INTEGER PRIMARY KEY,\n"
    "    scan_id     INTEGER NOT NULL REFERENCES scans (id),\n"
    "    point_index INTEGER NOT NULL CHECK (point_index >= 0),\n"
    "    stage_x_um  REAL    NOT NULL,\n"
    "    stage_y_um  REAL    NOT NULL,\n"
    "    stage_z_um  REAL    NOT NULL,\n"
    "    exposure_us REAL    NOT NULL CHECK (exposure_us > 0),\n"
    "    captured_ms INTEGER NOT NULL,\n"
    "    mean        BLOB    NOT NULL,\n"
    "    raw         BLOB    NOT NULL,\n"
    "    UNIQUE (scan_id, point_index)\n"
    ");\n"
    "CREATE TABLE jobs (\n"
    "    id           INTEGER PRIMARY KEY,\n"
    "    kind         TEXT    NOT NULL CHECK (kind IN ('scan', 'fit')),\n"
    "    params       TEXT    NOT NULL CONSTRAINT params_json CHECK (json_valid(params)),\n"
    "    state        TEXT    NOT NULL DEFAULT 'queued'\n"
    "                 CHECK (state IN ('queued', 'running', 'done', 'failed', 'cancelled')),\n"
    "    progress     REAL    NOT NULL DEFAULT 0 CHECK (progress BETWEEN 0 AND 1),\n"
    "    points_done  INTEGER NOT NULL DEFAULT 0 CHECK (points_done >= 0),\n"
    "    error        TEXT,\n"
    "    attempts     INTEGER NOT NULL DEFAULT 0,\n"
    "    heartbeat_ms INTEGER,\n"
    "    created_ms   INTEGER NOT NULL,\n"
    "    started_ms   INTEGER,\n"
    "    finished_ms  INTEGER,\n"
    "    scan_id      INTEGER REFERENCES scans (id),\n"
    "    fit_id       INTEGER REFERENCES fits (id)\n"
    ");\n"
    "CREATE INDEX jobs_queue ON jobs (kind, state, id);\n"
    "CREATE INDEX jobs_scan ON jobs (scan_id);\n"
    "CREATE TABLE fits (\n"
    "    id          INTEGER PRIMARY KEY,\n"
    "    scan_id     INTEGER NOT NULL REFERENCES scans (id),\n"
    "    dcol        INTEGER NOT NULL,\n"
    "    drow        INTEGER NOT NULL,\n"
    "    noise_model TEXT    NOT NULL CHECK (length(noise_model) > 0),\n"
    "    best_r_aic  INTEGER,\n"
    "    best_r_bic  INTEGER,\n"
    "    f_value     REAL,\n"
    "    p_value     REAL,\n"
    "    result      TEXT    NOT NULL CONSTRAINT result_json CHECK (json_valid(result)),\n"
    "    created_ms  INTEGER NOT NULL\n"
    ");\n"
    "CREATE INDEX fits_scan_pixel ON fits (scan_id, drow, dcol);\n"
    "CREATE TABLE calibrations (\n"
    "    id               INTEGER PRIMARY KEY,\n"
    "    sensor_id        INTEGER NOT NULL REFERENCES sensors (id),\n"
    "    pixel_col        INTEGER NOT NULL CHECK (pixel_col >= 0),\n"
    "    pixel_row        INTEGER NOT NULL CHECK (pixel_row >= 0),\n"
    "    r                INTEGER NOT NULL CHECK (r BETWEEN 1 AND 64),\n"
    "    s                BLOB    NOT NULL CHECK (length(s) = 8 * r * r),\n"
    "    s_err            BLOB    NOT NULL CHECK (length(s_err) = 8 * r * r),\n"
    "    i0               REAL,\n"
    "    chi2_red         REAL,\n"
    "    status           TEXT    NOT NULL CHECK (length(status) > 0),\n"
    "    scan_id          INTEGER REFERENCES scans (id),\n"
    "    fit_id           INTEGER REFERENCES fits (id),\n"
    "    noise_model      TEXT    NOT NULL CHECK (length(noise_model) > 0),\n"
    "    wavelength_um    REAL,\n"
    "    na               REAL,\n"
    "    spot_radius_um   REAL,\n"
    "    software_version TEXT    NOT NULL,\n"
    "    created_ms       INTEGER NOT NULL,\n"
    "    superseded_by    INTEGER REFERENCES calibrations (id) DEFERRABLE INITIALLY DEFERRED\n"
    ");\n"
    /* at most one current calibration per sensor pixel, enforced by the database itself */
    "CREATE UNIQUE INDEX calibrations_current ON calibrations (sensor_id, pixel_row, pixel_col)\n"
    "    WHERE superseded_by IS NULL;\n"
    "CREATE INDEX calibrations_pixel ON calibrations (sensor_id, pixel_row, pixel_col, id);\n"
    "CREATE INDEX calibrations_created ON calibrations (created_ms);\n"
    "PRAGMA user_version = 1;\n",

    /* 2: scans.setup (what the scan procedure found: the centre, exposure and sensor constants a
     * resumed raster and the pixel extraction need), and fits.scan_id may be NULL (a fit of an
     * uploaded scan file). SQLite cannot drop a NOT NULL, so fits is rebuilt the documented way
     * (storage_open runs migrations with foreign keys off and checks them before turning them
     * on); its ids are kept, so the references of jobs and calibrations stay valid. */
    "ALTER TABLE scans ADD COLUMN setup TEXT\n"
    "    CONSTRAINT setup_json CHECK (setup IS NULL OR json_valid(setup));\n"
    "CREATE TABLE fits_v2 (\n"
    "    id          INTEGER PRIMARY KEY,\n"
    "    scan_id     INTEGER REFERENCES scans (id),\n"
    "    dcol        INTEGER NOT NULL,\n"
    "    drow        INTEGER NOT NULL,\n"
    "    noise_model TEXT    NOT NULL CHECK (length(noise_model) > 0),\n"
    "    best_r_aic  INTEGER,\n"
    "    best_r_bic  INTEGER,\n"
    "    f_value     REAL,\n"
    "    p_value     REAL,\n"
    "    result      TEXT    NOT NULL CONSTRAINT result_json CHECK (json_valid(result)),\n"
    "    created_ms  INTEGER NOT NULL\n"
    ");\n"
    "INSERT INTO fits_v2 (id, scan_id, dcol, drow, noise_model, best_r_aic, best_r_bic, f_value,\n"
    "    p_value, result, created_ms)\n"
    "    SELECT id, scan_id, dcol, drow, noise_model, best_r_aic, best_r_bic, f_value, p_value,\n"
    "    result, created_ms FROM fits;\n"
    "DROP TABLE fits;\n"
    "ALTER TABLE fits_v2 RENAME TO fits;\n"
    "CREATE INDEX fits_scan_pixel ON fits (scan_id, drow, dcol);\n"
    "PRAGMA user_version = 2;\n",

    /* 3: the lab database changes only on purpose. fit_maps keeps the map each fit offers as its
     * pixel's calibration (the recommended map and its target pixel), so that a fit stored
     * without becoming the calibration can be promoted later, and any earlier fit promoted again;
     * it is filled from the calibrations the fits made so far. calibrations gets its provenance:
     * the calibration it superseded (from superseded_by, the reverse link), who made it current
     * and why (a declared name; earlier rows were all stored automatically by ipsd when their fit
     * finished). Existing rows are kept as they are; ALTER TABLE ADD COLUMN keeps every row. */
    "CREATE TABLE fit_maps (\n"
    "    fit_id           INTEGER PRIMARY KEY REFERENCES fits (id),\n"
    "    sensor_id        INTEGER NOT NULL REFERENCES sensors (id),\n"
    "    pixel_col        INTEGER NOT NULL CHECK (pixel_col >= 0),\n"
    "    pixel_row        INTEGER NOT NULL CHECK (pixel_row >= 0),\n"
    "    r                INTEGER NOT NULL CHECK (r BETWEEN 1 AND 64),\n"
    "    s                BLOB    NOT NULL CHECK (length(s) = 8 * r * r),\n"
    "    s_err            BLOB    NOT NULL CHECK (length(s_err) = 8 * r * r),\n"
    "    i0               REAL,\n"
    "    chi2_red         REAL,\n"
    "    status           TEXT    NOT NULL CHECK (length(status) > 0),\n"
    "    wavelength_um    REAL,\n"
    "    na               REAL,\n"
    "    spot_radius_um   REAL,\n"
    "    software_version TEXT    NOT NULL\n"
    ");\n"
    "INSERT INTO fit_maps (fit_id, sensor_id, pixel_col, pixel_row, r, s, s_err, i0, chi2_red,\n"
    "    status, wavelength_um, na, spot_radius_um, software_version)\n"
    "    SELECT fit_id, sensor_id, pixel_col, pixel_row, r, s, s_err, i0, chi2_red, status,\n"
    "    wavelength_um, na, spot_radius_um, software_version FROM calibrations\n"
    "    WHERE id IN (SELECT min(id) FROM calibrations WHERE fit_id IS NOT NULL GROUP BY fit_id);\n"
    "ALTER TABLE calibrations ADD COLUMN supersedes INTEGER REFERENCES calibrations (id);\n"
    "ALTER TABLE calibrations ADD COLUMN changed_by TEXT NOT NULL DEFAULT 'ipsd';\n"
    "ALTER TABLE calibrations ADD COLUMN reason TEXT NOT NULL DEFAULT '';\n"
    "UPDATE calibrations SET supersedes =\n"
    "    (SELECT o.id FROM calibrations o WHERE o.superseded_by = calibrations.id),\n"
    "    reason = 'stored when its fit finished (before schema 3 recorded reasons)';\n"
    "CREATE INDEX calibrations_fit ON calibrations (fit_id);\n"
    "PRAGMA user_version = 3;\n",

    /* 4: photon-transfer measurements (EMVA 1288) of a sensor, every one kept: the history of
     * its gain and read noise. The newest row is the sensor's measured constants; the sensors
     * row keeps the constants it was created with. */
    "CREATE TABLE ptc (\n"
    "    id                  INTEGER PRIMARY KEY,\n"
    "    sensor_id           INTEGER NOT NULL REFERENCES sensors (id),\n"
    "    gain_e_per_dn       REAL    NOT NULL CHECK (gain_e_per_dn > 0),\n"
    "    read_noise_e        REAL    NOT NULL CHECK (read_noise_e >= 0),\n"
    "    dark_dn             REAL,\n"
    "    saturation_dn       REAL,\n"
    "    linearity_error_pct REAL,\n"
    "    result              TEXT    NOT NULL CONSTRAINT result_json CHECK (json_valid(result)),\n"
    "    job_id              INTEGER REFERENCES jobs (id),\n"
    "    created_ms          INTEGER NOT NULL\n"
    ");\n"
    "CREATE INDEX ptc_sensor ON ptc (sensor_id, id);\n"
    "PRAGMA user_version = 4;\n",

    /* 5: photon-transfer jobs (kind 'ptc', run by the scan worker: it owns the instrument). A
     * CHECK cannot be altered, so jobs is rebuilt the documented way (new table, copy, drop,
     * rename; storage_open runs it in one transaction with foreign keys off and checks them
     * after): every row and id is kept, so the references of ptc to jobs stay valid. */
    "CREATE TABLE jobs_v5 (\n"
    "    id           INTEGER PRIMARY KEY,\n"
    "    kind         TEXT    NOT NULL CHECK (kind IN ('scan', 'fit', 'ptc')),\n"
    "    params       TEXT    NOT NULL CONSTRAINT params_json CHECK (json_valid(params)),\n"
    "    state        TEXT    NOT NULL DEFAULT 'queued'\n"
    "                 CHECK (state IN ('queued', 'running', 'done', 'failed', 'cancelled')),\n"
    "    progress     REAL    NOT NULL DEFAULT 0 CHECK (progress BETWEEN 0 AND 1),\n"
    "    points_done  INTEGER NOT NULL DEFAULT 0 CHECK (points_done >= 0),\n"
    "    error        TEXT,\n"
    "    attempts     INTEGER NOT NULL DEFAULT 0,\n"
    "    heartbeat_ms INTEGER,\n"
    "    created_ms   INTEGER NOT NULL,\n"
    "    started_ms   INTEGER,\n"
    "    finished_ms  INTEGER,\n"
    "    scan_id      INTEGER REFERENCES scans (id),\n"
    "    fit_id       INTEGER REFERENCES fits (id)\n"
    ");\n"
    "INSERT INTO jobs_v5 (id, kind, params, state, progress, points_done, error, attempts,\n"
    "    heartbeat_ms, created_ms, started_ms, finished_ms, scan_id, fit_id)\n"
    "    SELECT id, kind, params, state, progress, points_done, error, attempts, heartbeat_ms,\n"
    "    created_ms, started_ms, finished_ms, scan_id, fit_id FROM jobs;\n"
    "DROP TABLE jobs;\n"
    "ALTER TABLE jobs_v5 RENAME TO jobs;\n"
    "CREATE INDEX jobs_queue ON jobs (kind, state, id);\n"
    "CREATE INDEX jobs_scan ON jobs (scan_id);\n"
    "PRAGMA user_version = 5;\n",

    /* 6: each fit knows the job that stored it (fits.job_id), so the fits of a job of every
     * pixel are a query (the job's fit_ids: its fits in id order, the order stored), not a list
     * kept in the job's params. Filled from the links schema 5 kept: a job's fit_id (its fit;
     * a job of every pixel: its newest) and the params' "fit_ids" of a job of every pixel, which
     * then leave the params (they are the request again, as every other job's). ALTER TABLE ADD
     * COLUMN keeps every row and id. Fits are never deleted and get ascending ids, so id order
     * is the order a job stored them. */
    "ALTER TABLE fits ADD COLUMN job_id INTEGER REFERENCES jobs (id);\n"
    "UPDATE fits SET job_id = (SELECT min(j.id) FROM jobs j WHERE j.fit_id = fits.id);\n"
    "UPDATE fits SET job_id = (SELECT min(j.id) FROM jobs j, json_each(j.params, '$.fit_ids') e\n"
    "    WHERE e.value = fits.id)\n"
    "    WHERE id IN (SELECT e.value FROM jobs j, json_each(j.params, '$.fit_ids') e);\n"
    "UPDATE jobs SET params = json_remove(params, '$.fit_ids')\n"
    "    WHERE json_type(params, '$.fit_ids') IS NOT NULL;\n"
    "CREATE INDEX fits_job ON fits (job_id);\n"
    "PRAGMA user_version = 6;\n",

    /* 7: which map a fit offers and a calibration holds: 'recommended' (the recommended r's own
     * fit) or 'shrunk' (its detail shrunk toward r - 1, fit/shrink.h), asked by a fit request's
     * "map": "shrunk" (docs/api.md). Filled from what schema 6 recorded: a fit whose job asked
     * for the shrunk map and whose document has one (fits.result's shrunk_map; without one the
     * job stored the recommended map), and every calibration of such a fit. And s_res, the map's
     * resolution error (fit/shrink.h's S_res, r*r float64; NULL: not known, as for every row
     * before schema 7). ALTER TABLE ADD COLUMN keeps every row and id. */
    "ALTER TABLE fit_maps ADD COLUMN map TEXT NOT NULL DEFAULT 'recommended'\n"
    "    CHECK (map IN ('recommended', 'shrunk'));\n"
    "ALTER TABLE calibrations ADD COLUMN map TEXT NOT NULL DEFAULT 'recommended'\n"
    "    CHECK (map IN ('recommended', 'shrunk'));\n"
    "ALTER TABLE fit_maps ADD COLUMN s_res BLOB CHECK (s_res IS NULL OR length(s_res) = 8 * r * r);\n"
    "ALTER TABLE calibrations ADD COLUMN s_res BLOB\n"
    "    CHECK (s_res IS NULL OR length(s_res) = 8 * r * r);\n"
    "UPDATE fit_maps SET map = 'shrunk' WHERE fit_id IN (SELECT f.id FROM fits f\n"
    "    JOIN jobs j ON j.id = f.job_id WHERE json_extract(j.params, '$.map') = 'shrunk'\n"
    "    AND json_type(f.result, '$.shrunk_map') = 'object');\n"
    "UPDATE calibrations SET map = 'shrunk'\n"
    "    WHERE fit_id IN (SELECT fit_id FROM fit_maps WHERE map = 'shrunk');\n"
    "PRAGMA user_version = 7;\n",

    /* 8: a third map, 'kriged' (the kriged map on its fine F x F grid, fit/krige.h; r is then F,
     * at most 46 for r <= 32), asked by a fit request's "map": "kriged". A CHECK cannot be
     * altered, so fit_maps and calibrations are rebuilt the documented way (new table with the
     * same columns in the same order, copy, drop, rename, indexes again; storage_open runs it in
     * one transaction with foreign keys off and checks them after): every row and id is kept, so
     * calibrations' links to each other and the fits' to their maps stay valid. */
    "CREATE TABLE fit_maps_v8 (\n"
    "    fit_id           INTEGER PRIMARY KEY REFERENCES fits (id),\n"
    "    sensor_id        INTEGER NOT NULL REFERENCES sensors (id),\n"
    "    pixel_col        INTEGER NOT NULL CHECK (pixel_col >= 0),\n"
    "    pixel_row        INTEGER NOT NULL CHECK (pixel_row >= 0),\n"
    "    r                INTEGER NOT NULL CHECK (r BETWEEN 1 AND 64),\n"
    "    s                BLOB    NOT NULL CHECK (length(s) = 8 * r * r),\n"
    "    s_err            BLOB    NOT NULL CHECK (length(s_err) = 8 * r * r),\n"
    "    i0               REAL,\n"
    "    chi2_red         REAL,\n"
    "    status           TEXT    NOT NULL CHECK (length(status) > 0),\n"
    "    wavelength_um    REAL,\n"
    "    na               REAL,\n"
    "    spot_radius_um   REAL,\n"
    "    software_version TEXT    NOT NULL,\n"
    "    map              TEXT    NOT NULL DEFAULT 'recommended'\n"
    "                     CHECK (map IN ('recommended', 'shrunk', 'kriged')),\n"
    "    s_res            BLOB    CHECK (s_res IS NULL OR length(s_res) = 8 * r * r)\n"
    ");\n"
    "INSERT INTO fit_maps_v8 (" FIT_MAP_COLUMNS_V7 ")\n"
    "    SELECT " FIT_MAP_COLUMNS_V7 " FROM fit_maps;\n"
    "DROP TABLE fit_maps;\n"
    "ALTER TABLE fit_maps_v8 RENAME TO fit_maps;\n"
    "CREATE TABLE calibrations_v8 (\n"
    "    id               INTEGER PRIMARY KEY,\n"
    "    sensor_id        INTEGER NOT NULL REFERENCES sensors (id),\n"
    "    pixel_col        INTEGER NOT NULL CHECK (pixel_col >= 0),\n"
    "    pixel_row        INTEGER NOT NULL CHECK (pixel_row >= 0),\n"
    "    r                INTEGER NOT NULL CHECK (r BETWEEN 1 AND 64),\n"
    "    s                BLOB    NOT NULL CHECK (length(s) = 8 * r * r),\n"
    "    s_err            BLOB    NOT NULL CHECK (length(s_err) = 8 * r * r),\n"
    "    i0               REAL,\n"
    "    chi2_red         REAL,\n"
    "    status           TEXT    NOT NULL CHECK (length(status) > 0),\n"
    "    scan_id          INTEGER REFERENCES scans (id),\n"
    "    fit_id           INTEGER REFERENCES fits (id),\n"
    "    noise_model      TEXT    NOT NULL CHECK (length(noise_model) > 0),\n"
    "    wavelength_um    REAL,\n"
    "    na               REAL,\n"
    "    spot_radius_um   REAL,\n"
    "    software_version TEXT    NOT NULL,\n"
    "    created_ms       INTEGER NOT NULL,\n"
    "    superseded_by    INTEGER REFERENCES calibrations (id) DEFERRABLE INITIALLY DEFERRED,\n"
    "    supersedes       INTEGER REFERENCES calibrations (id),\n"
    "    changed_by       TEXT    NOT NULL DEFAULT 'ipsd',\n"
    "    reason           TEXT    NOT NULL DEFAULT '',\n"
    "    map              TEXT    NOT NULL DEFAULT 'recommended'\n"
    "                     CHECK (map IN ('recommended', 'shrunk', 'kriged')),\n"
    "    s_res            BLOB    CHECK (s_res IS NULL OR length(s_res) = 8 * r * r)\n"
    ");\n"
    "INSERT INTO calibrations_v8 (" CALIBRATION_COLUMNS_V7 ")\n"
    "    SELECT " CALIBRATION_COLUMNS_V7 " FROM calibrations;\n"
    "DROP TABLE calibrations;\n"
    "ALTER TABLE calibrations_v8 RENAME TO calibrations;\n"
    "CREATE UNIQUE INDEX calibrations_current ON calibrations (sensor_id, pixel_row, pixel_col)\n"
    "    WHERE superseded_by IS NULL;\n"
    "CREATE INDEX calibrations_pixel ON calibrations (sensor_id, pixel_row, pixel_col, id);\n"
    "CREATE INDEX calibrations_created ON calibrations (created_ms);\n"
    "CREATE INDEX calibrations_fit ON calibrations (fit_id);\n"
    "PRAGMA user_version = 8;\n",

    /* 9: map_note, one sentence on how the map was made when it is not the map its fit asked
     * for (no kriged map could be made: no signal, too few points); NULL otherwise, and for every
     * older row */
    "ALTER TABLE fit_maps ADD COLUMN map_note TEXT CHECK (map_note IS NULL OR length(map_note) > 0);\n"
    "ALTER TABLE calibrations ADD COLUMN map_note TEXT\n"
    "    CHECK (map_note IS NULL OR length(map_note) > 0);\n"
    "PRAGMA user_version = 9;\n",

    /* 10: each frame's timestamp (start of exposure, the camera backend's clock, ns) and the
     * camera's own frame id, k int64 / uint64 little-endian each; NULL: not recorded (a camera
     * without frame ids). A table beside frames, not columns after raw: a column after a large
     * BLOB is reached only through its overflow pages, and a point's head must not read them. */
    "CREATE TABLE frame_times (\n"
    "    scan_id          INTEGER NOT NULL REFERENCES scans (id),\n"
    "    point_index      INTEGER NOT NULL CHECK (point_index >= 0),\n"
    "    timestamps_ns    BLOB    CHECK (timestamps_ns IS NULL OR length(timestamps_ns) % 8 = 0),\n"
    "    camera_frame_ids BLOB\n"
    "                     CHECK (camera_frame_ids IS NULL OR length(camera_frame_ids) % 8 = 0),\n"
    "    PRIMARY KEY (scan_id, point_index)\n"
    ");\n"
    "PRAGMA user_version = 10;\n",
    /* 11: several ipsd on one database (PostgreSQL). bench: the bench whose instrument runs a
     * scan or photon-transfer job (NULL: any ipsd may claim it, as every fit job); claimed_by:
     * the ipsd (its bench name) that claimed it last, whose heartbeat is the job's lease. */
    "ALTER TABLE jobs ADD COLUMN bench TEXT CHECK (bench IS NULL OR length(bench) > 0);\n"
    "ALTER TABLE jobs ADD COLUMN claimed_by TEXT;\n"
    "PRAGMA user_version = 11;\n",
    /* 12: a database copied into another (ipsd --db-copy). database_info: this database's own
     * id (random, made once), which names it as the origin of what it gives another; copied_rows:
     * each row copied here from an origin, its id there and here, so a second copy of the same
     * origin copies nothing twice. */
    "CREATE TABLE database_info (\n"
    "    id         TEXT    NOT NULL CHECK (length(id) = 32),\n"
    "    created_ms INTEGER NOT NULL\n"
    ");\n"
    "INSERT INTO database_info VALUES (lower(hex(randomblob(16))), "
    "CAST((julianday('now') - 2440587.5) * 86400000 AS INTEGER));\n"
    "CREATE TABLE copied_rows (\n"
    "    origin    TEXT    NOT NULL,\n"
    "    tbl       TEXT    NOT NULL,\n"
    "    source_id INTEGER NOT NULL,\n"
    "    target_id INTEGER NOT NULL,\n"
    "    PRIMARY KEY (origin, tbl, source_id)\n"
    ");\n"
    "PRAGMA user_version = 12;\n",
};
const int stg_n_migrations = (int)(sizeof stg_migrations / sizeof stg_migrations[0]);

#define SCAN_FILTER "WHERE (?1 IS NULL OR sensor_id = ?1) AND (?2 IS NULL OR state = ?2)"
#define JOB_FILTER                                                                                \
    "WHERE (?1 IS NULL OR kind = ?1) AND (?2 IS NULL OR state = ?2) "                             \
    "AND (?3 IS NULL OR scan_id = ?3)"
#define CALIB_FILTER                                                                              \
    "FROM calibrations c JOIN sensors s ON s.id = c.sensor_id "                                   \
    "WHERE (?1 IS NULL OR c.sensor_id = ?1) AND (?2 IS NULL OR s.model = ?2) "                    \
    "AND (?3 IS NULL OR c.pixel_col >= ?3) AND (?4 IS NULL OR c.pixel_col <= ?4) "                \
    "AND (?5 IS NULL OR c.pixel_row >= ?5) AND (?6 IS NULL OR c.pixel_row <= ?6) "                \
    "AND (?7 IS NULL OR c.created_ms >= ?7) AND (?8 IS NULL OR c.status = ?8) "                   \
    "AND (?9 = 0 OR c.superseded_by IS NULL)"
/* a fit, the map it offers (fit_maps) and the current calibration of that map's pixel */
#define FIT_FROM                                                                                  \
    "FROM fits f LEFT JOIN fit_maps m ON m.fit_id = f.id "                                        \
    "LEFT JOIN calibrations c ON c.sensor_id = m.sensor_id AND c.pixel_col = m.pixel_col "        \
    "AND c.pixel_row = m.pixel_row AND c.superseded_by IS NULL"
#define FINAL_STATES "('done', 'failed', 'cancelled')"

const char *const stg_sql[STG_N] = {
    [STG_BEGIN_WRITE] = "BEGIN IMMEDIATE",
    [STG_BEGIN_READ] = "BEGIN",
    [STG_COMMIT] = "COMMIT",
    [STG_ROLLBACK] = "ROLLBACK",
    [STG_USER_VERSION] = "PRAGMA user_version",
    [STG_PAGE_COUNT] = "PRAGMA page_count",
    [STG_FREELIST_COUNT] = "PRAGMA freelist_count",

    [STG_SENSOR_INSERT] =
        "INSERT INTO sensors (model, serial, n_cols, n_rows, pitch_um, gain_e_per_dn, "
        "read_noise_e, bias_dn, full_scale_dn, created_ms) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
    [STG_SENSOR_GET] = "SELECT " STG_SENSOR_COLS " FROM sensors WHERE id = ?1",
    [STG_SENSOR_FIND] = "SELECT " STG_SENSOR_COLS " FROM sensors WHERE model = ?1 AND serial = ?2",
    [STG_SENSOR_LIST] = "SELECT " STG_SENSOR_COLS " FROM sensors ORDER BY id LIMIT ?1 OFFSET ?2",
    [STG_SENSOR_COUNT] = "SELECT count(*) FROM sensors",

    [STG_SCAN_INSERT] =
        "INSERT INTO scans (sensor_id, poi_col, poi_row, wavelength_um, na, spot_radius_um, "
        "area_px, step_um, sub_px, frames, exposure_us, points_total, state, points_done, "
        "created_ms) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, 'queued', 0, ?13)",
    [STG_SCAN_GET] = "SELECT " STG_SCAN_COLS " FROM scans WHERE id = ?1",
    [STG_SCAN_COUNT] = "SELECT count(*) FROM scans " SCAN_FILTER,
    [STG_SCAN_LIST] =
        "SELECT " STG_SCAN_COLS ", " STG_SCAN_JOB_PARAMS " FROM scans " SCAN_FILTER
        " ORDER BY id DESC LIMIT ?3 OFFSET ?4",
    [STG_SCAN_SET_STATE] =
        "UPDATE scans SET state = ?2, error = ?3, "
        "started_ms = CASE WHEN ?2 = 'running' THEN coalesce(started_ms, ?4) ELSE started_ms END, "
        "finished_ms = CASE WHEN ?2 IN " FINAL_STATES " THEN ?4 ELSE NULL END "
        "WHERE id = ?1",
    [STG_SCAN_ADD_POINT] = "UPDATE scans SET points_done = points_done + 1 WHERE id = ?1",
    [STG_SCAN_SET_SETUP] = "UPDATE scans SET setup = ?2 WHERE id = ?1",
    [STG_SCAN_GET_SETUP] = "SELECT setup FROM scans WHERE id = ?1",
    /* an adaptive scan's count, once it has stopped (storage_scan_set_points_total) */
    [STG_SCAN_SET_TOTAL] = "UPDATE scans SET points_total = ?2 WHERE id = ?1 AND points_done <= ?2",
    /* a failed scan and its failed scan job queued again (storage_scan_resume) */
    [STG_SCAN_RESUME] = "UPDATE scans SET state = 'queued', error = NULL, finished_ms = NULL "
                        "WHERE id = ?1 AND state = 'failed'",
    [STG_JOB_RESUME] =
        "UPDATE jobs SET state = 'queued', error = NULL, finished_ms = NULL, heartbeat_ms = NULL, "
        "attempts = 0 WHERE id = (SELECT max(id) FROM jobs WHERE kind = 'scan' AND scan_id = ?1) "
        "AND state = 'failed' RETURNING id",
    [STG_SCAN_CANCEL] = "UPDATE scans SET state = 'cancelled', finished_ms = ?2 "
                        "WHERE id = ?1 AND state IN ('queued', 'running')",

    [STG_FRAME_INSERT] =
        "INSERT INTO frames (scan_id, point_index, stage_x_um, stage_y_um, stage_z_um, "
        "exposure_us, captured_ms, mean, raw) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
    [STG_FRAME_TIMES_INSERT] =
        "INSERT INTO frame_times (scan_id, point_index, timestamps_ns, camera_frame_ids) "
        "VALUES (?1, ?2, ?3, ?4)",
    [STG_FRAME_TIMES_GET] =
        "SELECT timestamps_ns, camera_frame_ids FROM frame_times "
        "WHERE scan_id = ?1 AND point_index = ?2",
    [STG_FRAME_GET] =
        "SELECT stage_x_um, stage_y_um, stage_z_um, exposure_us, captured_ms, mean, raw "
        "FROM frames WHERE scan_id = ?1 AND point_index = ?2",
    /* the raw frames' size and row id, not the frames: length() of a blob reads no overflow
       page, and the frames wanted are read by sqlite3_blob_read (storage_frame_get_part) */
    [STG_FRAME_HEAD] =
        "SELECT stage_x_um, stage_y_um, stage_z_um, exposure_us, captured_ms, mean, id, "
        "length(raw) FROM frames WHERE scan_id = ?1 AND point_index = ?2",
    [STG_FRAME_LAST] =
        "SELECT coalesce(max(point_index), -1), count(*) FROM frames WHERE scan_id = ?1",
    /* ?2 is the 1-based byte offset of the pixel's float64 in the mean BLOB */
    [STG_FRAME_RASTER] =
        "SELECT point_index, stage_x_um, stage_y_um, exposure_us, substr(mean, ?2, 8) "
        "FROM frames WHERE scan_id = ?1 ORDER BY point_index",
    [STG_FRAME_MEANS] = "SELECT point_index, stage_x_um, stage_y_um, mean "
                        "FROM frames WHERE scan_id = ?1 ORDER BY point_index",

    [STG_JOB_INSERT] = "INSERT INTO jobs (kind, params, state, created_ms, scan_id, bench) "
                       "VALUES (?1, ?2, 'queued', ?3, ?4, ?5)",
    [STG_JOB_GET] = "SELECT " STG_JOB_COLS " FROM jobs WHERE id = ?1",
    /* the oldest queued job of up to three kinds (NULL: no kind) that this ipsd may run: one
     * of no bench, or of its own bench (?4) */
    [STG_JOB_NEXT] = "SELECT id FROM jobs WHERE kind IN (?1, ?2, ?3) AND state = 'queued' "
                     "AND (bench IS NULL OR bench = ?4) ORDER BY id LIMIT 1",
    [STG_JOB_START] = "UPDATE jobs SET state = 'running', attempts = attempts + 1, "
                      "heartbeat_ms = ?2, started_ms = coalesce(started_ms, ?2), claimed_by = ?3 "
                      "WHERE id = ?1 AND state = 'queued'",
    /* a running job changes only through its claimant (?N: this handle's name, NULL unnamed): a
     * job whose lease another ipsd took over is no longer the late one's to report or end */
    [STG_JOB_HEARTBEAT] = "UPDATE jobs SET heartbeat_ms = ?2, progress = ?3, points_done = ?4 "
                          "WHERE id = ?1 AND state = 'running' AND claimed_by IS ?5",
    [STG_JOB_FINISH] =
        "UPDATE jobs SET state = ?2, error = ?3, finished_ms = ?4, heartbeat_ms = ?4, "
        "progress = CASE WHEN ?2 = 'done' THEN 1 ELSE progress END "
        "WHERE id = ?1 AND state = 'running' AND claimed_by IS ?5",
    [STG_JOB_CANCEL] = "UPDATE jobs SET state = 'cancelled', finished_ms = ?2 "
                       "WHERE id = ?1 AND state IN ('queued', 'running')",
    [STG_JOB_STATE] = "SELECT state, kind, scan_id, claimed_by FROM jobs WHERE id = ?1",
    [STG_JOB_ABANDON] =
        "UPDATE jobs SET state = 'failed', finished_ms = ?3, "
        "error = 'abandoned after ' || attempts || ' attempts (stale heartbeat)' "
        "WHERE state = 'running' AND coalesce(heartbeat_ms, 0) <= ?1 AND ?2 > 0 AND attempts >= ?2 "
        "AND (?4 IS NULL OR claimed_by = ?4)",
    /* ?2: only the jobs this claimant left running (NULL: anyone's) */
    [STG_JOB_REQUEUE] = "UPDATE jobs SET state = 'queued', heartbeat_ms = NULL "
                        "WHERE state = 'running' AND coalesce(heartbeat_ms, 0) <= ?1 "
                        "AND (?2 IS NULL OR claimed_by = ?2)",
    /* a graceful stop gives the claim back: the job runs again as if never claimed */
    [STG_JOB_RELEASE] = "UPDATE jobs SET state = 'queued', heartbeat_ms = NULL, "
                        "attempts = max(attempts - 1, 0) WHERE id = ?1 AND state = 'running' "
                        "AND claimed_by IS ?2",
    [STG_JOB_COUNT] = "SELECT count(*) FROM jobs " JOB_FILTER,
    [STG_JOB_LIST] =
        "SELECT " STG_JOB_COLS " FROM jobs " JOB_FILTER " ORDER BY id DESC LIMIT ?4 OFFSET ?5",
    [STG_JOB_SET_FIT] = "UPDATE jobs SET fit_id = ?2 WHERE id = ?1",
    /* one unit of a running job done: only from the count the caller read (no unit twice) */
    [STG_JOB_STEP] = "UPDATE jobs SET points_done = ?3, progress = ?4, heartbeat_ms = ?5 "
                     "WHERE id = ?1 AND state = 'running' AND points_done = ?2 "
                     "AND claimed_by IS ?6",

    [STG_FIT_INSERT] = "INSERT INTO fits (scan_id, dcol, drow, noise_model, best_r_aic, "
                       "best_r_bic, f_value, p_value, result, created_ms) "
                       "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
    [STG_FIT_GET] = "SELECT " STG_FIT_COLS " " FIT_FROM " WHERE f.id = ?1",
    [STG_FIT_COUNT] = "SELECT count(*) FROM fits WHERE scan_id = ?1",
    [STG_FIT_LIST] = "SELECT " STG_FIT_COLS " " FIT_FROM " WHERE f.scan_id = ?1 "
                     "ORDER BY f.id DESC LIMIT ?2 OFFSET ?3",
    /* the job that stored the fit (schema 6) */
    [STG_FIT_SET_JOB] = "UPDATE fits SET job_id = ?2 WHERE id = ?1",
    [STG_FIT_MAP_INSERT] =
        "INSERT INTO fit_maps (fit_id, sensor_id, pixel_col, pixel_row, r, s, s_err, i0, "
        "chi2_red, status, wavelength_um, na, spot_radius_um, software_version, map, s_res, "
        "map_note) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17)",
    /* one row for a known fit, its map columns NULL when it offers none */
    [STG_FIT_MAP_GET] = "SELECT " STG_FIT_MAP_COLS " FROM fits f "
                        "LEFT JOIN fit_maps m ON m.fit_id = f.id WHERE f.id = ?1",

    [STG_CALIB_CURRENT_ID] =
        "SELECT id, fit_id FROM calibrations WHERE sensor_id = ?1 AND pixel_col = ?2 "
        "AND pixel_row = ?3 AND superseded_by IS NULL",
    /* the id the next INSERT would get anyway: known before the INSERT so that the old row can
     * point to it first (superseded_by is a deferred foreign key; see storage_calib.c) */
    [STG_CALIB_NEXT_ID] = "SELECT coalesce(max(id), 0) + 1 FROM calibrations",
    [STG_CALIB_SUPERSEDE] = "UPDATE calibrations SET superseded_by = ?2 WHERE id = ?1",
    [STG_CALIB_INSERT] =
        "INSERT INTO calibrations (id, sensor_id, pixel_col, pixel_row, r, s, s_err, i0, "
        "chi2_red, status, scan_id, fit_id, noise_model, wavelength_um, na, spot_radius_um, "
        "software_version, created_ms, supersedes, changed_by, reason, map, s_res, map_note) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, "
        "?19, ?20, ?21, ?22, ?23, ?24)",
    [STG_CALIB_GET] = "SELECT " STG_CALIB_COLS " FROM calibrations c WHERE c.id = ?1",
    [STG_CALIB_CURRENT] =
        "SELECT " STG_CALIB_COLS " FROM calibrations c WHERE c.sensor_id = ?1 "
        "AND c.pixel_col = ?2 AND c.pixel_row = ?3 AND c.superseded_by IS NULL",
    [STG_CALIB_HISTORY] = "SELECT " STG_CALIB_COLS " FROM calibrations c WHERE c.sensor_id = ?1 "
                          "AND c.pixel_col = ?2 AND c.pixel_row = ?3 ORDER BY c.id DESC",
    [STG_CALIB_COUNT] = "SELECT count(*) " CALIB_FILTER,
    [STG_PTC_INSERT] = "INSERT INTO ptc (sensor_id, gain_e_per_dn, read_noise_e, dark_dn, "
                       "saturation_dn, linearity_error_pct, result, job_id, created_ms) "
                       "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)",
    [STG_PTC_GET] = "SELECT " STG_PTC_COLS " FROM ptc WHERE id = ?1",
    [STG_PTC_HISTORY] = "SELECT " STG_PTC_COLS " FROM ptc WHERE sensor_id = ?1 "
                        "ORDER BY id DESC LIMIT ?2",
    [STG_CALIB_SEARCH] = "SELECT " STG_CALIB_COLS " " CALIB_FILTER
                         " ORDER BY c.created_ms DESC, c.id DESC LIMIT ?10 OFFSET ?11",
};
