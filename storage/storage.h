/* storage.h: the ipsd database (SQLite): sensors, scans and their frames, the job queue, fit
 * results and the lab's calibration database of IPS maps. Every SQL statement of the project lives
 * in storage/; the schema and its BLOB layouts are documented in docs/schema.md.
 *
 * Threading: one storage_t per thread. A handle is its own SQLite connection (opened in
 * multi-thread mode) and must not be used by two threads at once; any number of handles (threads
 * or processes) may share one database file. The database runs in WAL mode, so readers never
 * block the writer nor each other; write transactions start with BEGIN IMMEDIATE and wait up to
 * the busy timeout (5000 ms by default) for another writer, then fail with -EBUSY.
 *
 * Durability: every function that writes commits before it returns (synchronous = FULL), and a
 * function either writes everything it says or nothing. storage_frame_put stores a scan point and
 * the scan's progress in one transaction, so a crash loses at most the point in flight.
 *
 * Errors: functions return 0 or a negative errno and, when err is not NULL, a one-line message:
 * -EINVAL bad arguments (the message names the field), -ENOENT unknown id, -EEXIST duplicate,
 * -EBUSY database locked longer than the busy timeout, -ECANCELED the job/scan was cancelled,
 * -ESTALE the job is not in the state the call needs, -ENOTSUP database newer than this code,
 * -ENOMEM, -EIO any other SQLite failure (with sqlite3_errmsg in the message).
 *
 * Ownership: structs filled by storage_*_get / _current / _claim own their strings and arrays;
 * release them with the matching storage_*_free (which accepts a zeroed or already freed struct
 * and zeroes it). Lists own their items; release with storage_*_list_free. Structs passed IN are
 * only read; storage copies what it keeps.
 *
 * Units: micrometres (_um), microseconds (_us), DN (digital numbers), electrons (_e); times are
 * milliseconds since the Unix epoch (UTC), 0 meaning "not yet". Maps are r*r float64, row-major
 * y then x (index j*r + i for column i, row j). Ids are > 0; 0 means "none". */
#ifndef IPSD_STORAGE_H
#define IPSD_STORAGE_H

#include <stddef.h>
#include <stdint.h>

#include "base/err.h"

typedef struct storage storage_t;

/* Process-wide SQLite settings, called once before any handle is opened (later it does
 * nothing): SQLite's memory statistics off, so its allocations take no global mutex that every
 * connection shares (a fit worker at a low priority holding it would stall the HTTP threads'
 * reads: docs/server.md, "Threads"). Returns 0 or -EBUSY (SQLite already initialised). */
int storage_process_setup(void);

/* A write gate: handles of one process that share it take the write lock first come, first
 * served (SQLite's busy handler is not fair: a handle committing a scan point every millisecond
 * starved a waiting fit worker and a cancel past the busy timeout). One per database, shared by
 * all of a server's handles; it must outlive them. The gate's wait has no deadline (in-process
 * write transactions are short); a thread that writes through one handle and begins a write
 * through another gets -EDEADLK instead of waiting for itself. */
typedef struct storage_gate storage_gate_t;
int storage_gate_new(storage_gate_t **out); /* 0 or -ENOMEM */
void storage_gate_free(storage_gate_t *g);
void storage_set_gate(storage_t *st, storage_gate_t *g);
/* The calibration generation of the gate's database: a counter that grows after every committed
 * transaction (of a handle sharing the gate) that stored a calibration; read before a read, it
 * tells a cache of calibration replies whether what it holds may be stale. -ENOTSUP without a
 * gate (then changes cannot be seen: do not cache); -EBUSY while a transaction that stored a
 * calibration has not ended (do not cache: what is read may be about to change). Writes by other
 * processes are not counted. */
int storage_calib_generation(storage_t *st, uint64_t *gen);

/* The storage's health as the gate saw it ("Storage faults"): every handle sharing the
 * gate records there a write (or read) that failed because of the storage itself - SQLITE_FULL
 * (fault -ENOSPC, "full"), SQLITE_READONLY (-EROFS, "read-only"), SQLITE_IOERR / SQLITE_CORRUPT /
 * SQLITE_CANTOPEN (-EIO, "io-error"); on PostgreSQL disk full 53100, a read-only transaction
 * 25006 or a privilege revoked 42501, lost connections and server errors alike - and a write
 * that commits clears it ("full": only when the
 * database then has more pages or more free pages than at the fault). msg: the last fault's
 * message (which names the database), kept after it clears; since_ms: when the current fault
 * began (wall clock), 0 when healthy; faults: how many failed operations so far. */
typedef struct storage_health {
    int fault;    /* 0 (ok), -ENOSPC, -EROFS or -EIO */
    char msg[256];
    int64_t since_ms;
    uint64_t faults;
} storage_health_t;
void storage_gate_health(storage_gate_t *g, storage_health_t *out);
/* "ok", "full", "read-only" or "io-error" for a health's fault. */
const char *storage_fault_name(int fault);

/* Test hooks of the gate (docs/server.md, "Test hooks"), both for storage faults made on purpose:
 * - fault_file: while that file exists, every write through the gate fails before it begins, with
 *   the SQLite error its first word names ("full": SQLITE_FULL, "ioerr": SQLITE_IOERR, "readonly":
 *   SQLITE_READONLY), as SQLite would report it. NULL or "": none. The path is copied.
 * - max_pages > 0: every handle given the gate afterwards (storage_set_gate) caps the database at
 *   that many pages (PRAGMA max_page_count), so SQLite itself answers SQLITE_FULL beyond it.
 * Returns 0 or -ENAMETOOLONG. */
/* On a PostgreSQL database (target a postgresql:// URI), starts the thread that hears of the
 * calibrations other ipsd store (storage_listen.c), so that storage_calib_generation moves for
 * them too; until it listens, storage_calib_generation answers -ENOTSUP there. No-op for an
 * SQLite file. 0 or a negative errno. */
int storage_gate_listen(storage_gate_t *g, const char *target, err_t *err);
int storage_gate_set_test_faults(storage_gate_t *g, const char *fault_file, long long max_pages);

/* The schema version this code creates and understands (PRAGMA user_version). */
int storage_schema_version(void);

/* Opens (creating the file if needed, not its directory) the database at path, switches it to WAL,
 * turns foreign keys on, and applies the forward migrations from the file's user_version to the
 * latest, each in its own transaction. A database with a newer user_version than this code knows
 * is refused with -ENOTSUP and left untouched. *out is owned by the caller: storage_close it. */
int storage_open(const char *path, storage_t **out, err_t *err);

/* Opens the database at path only to read it (the source of `ipsd --backup`): never created,
 * never migrated, nothing of it written. -EINVAL for a file that is not an SQLite database or
 * not an ipsd one (no schema version, or without ipsd's first tables), -ENOTSUP for a newer
 * schema than this code knows, -EIO when it cannot be read. Only reads may be made through
 * the handle (storage_backup, the getters); storage_close it. */
int storage_open_readonly(const char *path, storage_t **out, err_t *err);

/* Moves the write-ahead log into the database file and truncates the log to nothing (PRAGMA
 * wal_checkpoint(TRUNCATE)): after a storage fault, the log's space goes back to the file system
 * once the database file can take its pages. 0, -EBUSY (a reader or writer kept it from
 * finishing) or the storage error. */
int storage_checkpoint(storage_t *st, err_t *err);

/* Closes the connection and frees the handle. Accepts NULL; cannot fail. */
void storage_close(storage_t *st);

/* How long a write waits for another writer before -EBUSY (default 5000 ms). */
int storage_set_busy_timeout(storage_t *st, int ms, err_t *err);

/* The clock that stamps created/started/finished/heartbeat times: returns ms since the epoch.
 * Default (fn NULL): CLOCK_REALTIME. Tests and simulations may install their own. */
typedef int64_t (*storage_clock_fn)(void *ctx);
void storage_set_clock(storage_t *st, storage_clock_fn fn, void *ctx);

/* Names the ipsd this handle works for (its bench name; NULL: unnamed, the default): the scan
 * and ptc jobs it enqueues belong to that bench (only a handle of the same name claims them),
 * the jobs it claims record it, and a running job is reported on and ended only by a handle of
 * its claimant. 0 or -ENOMEM / -EINVAL (an empty name). */
int storage_set_claimant(storage_t *st, const char *name);

/* Takes, for the life of the handle, the database-wide lock of name (a shared PostgreSQL
 * database: an advisory lock a connection holds, released when the handle closes or its process dies),
 * or confirms that the handle holds it: 0 when it held it already, 1 when it has just taken it (the
 * first call, or after the handle's connection was opened again: a database server restart ends
 * the lock with the old connection), -EBUSY when another connection holds it, -ENOTSUP on an
 * SQLite file (one ipsd per file is a file lock there: server/srv.c). */
int storage_lock_name(storage_t *st, const char *name, err_t *err);

/* What storage_copy did: rows copied per table (frames: points of the scans copied), sensors
 * found in the target already (the same model and serial), and units skipped because an earlier
 * copy of the same source had copied them. */
typedef struct storage_copy_info {
    int64_t sensors, sensors_matched, scans, frames, jobs, fits, ptc, calibrations, skipped;
} storage_copy_info_t;

/* Copies every row of database from into database to (ipsd --db-copy: a bench's SQLite file into
 * the lab's PostgreSQL database), under the target's ids, keeping the provenance (states, times,
 * histories) and recording each copied row in the target (copied_rows, under the source's own id)
 * so that a second run copies only what is new. Scan and ptc jobs that name no bench get bench
 * (NULL: left without). Each unit is one transaction of the target (storage_copy.c). -EINVAL when
 * from and to are the same database; a negative errno naming the row that failed. */
int storage_copy(storage_t *from, storage_t *to, const char *bench, storage_copy_info_t *info,
                 err_t *err);

/* 1 when target names a PostgreSQL database (a postgresql:// or postgres:// URI: a database
 * several ipsd may share), 0 for an SQLite file. */
int storage_is_postgres(const char *target);
int64_t storage_now_ms(storage_t *st);

/* States of scans and jobs; stored as their names ("queued", "running", "done", "failed",
 * "cancelled"). STORAGE_ANY in a filter means "any". */
typedef enum storage_state {
    STORAGE_QUEUED = 0,
    STORAGE_RUNNING = 1,
    STORAGE_DONE = 2,
    STORAGE_FAILED = 3,
    STORAGE_CANCELLED = 4,
} storage_state_t;
#define STORAGE_ANY (-1)

/* Static name of a state, or NULL when out of range. */
const char *storage_state_name(int state);
/* Parses a state name; -EINVAL for an unknown one. */
int storage_state_parse(const char *name, storage_state_t *out);

/* ---- sensors ------------------------------------------------------------------------------ */

typedef struct storage_sensor {
    int64_t id;
    char *model, *serial;    /* non-empty; (model, serial) is unique */
    int n_cols, n_rows;      /* array size in pixels */
    double pitch_um;
    double gain_e_per_dn;    /* G */
    double read_noise_e;     /* read noise, electrons */
    double bias_dn;          /* B: ADC offset */
    double full_scale_dn;    /* ADC full scale (saturation) */
    int64_t created_ms;      /* set by storage */
} storage_sensor_t;

typedef struct storage_sensor_list {
    storage_sensor_t *items;
    size_t n;
    int64_t total;           /* rows matching (all sensors) */
} storage_sensor_list_t;

/* Stores a sensor (id and created_ms of s are ignored); *id gets the new id. -EEXIST when the
 * model/serial pair exists already. */
int storage_sensor_create(storage_t *st, const storage_sensor_t *s, int64_t *id, err_t *err);
/* Fills *out (caller frees with storage_sensor_free); -ENOENT for an unknown id. */
int storage_sensor_get(storage_t *st, int64_t id, storage_sensor_t *out, err_t *err);
/* Looks a sensor up by model and serial; -ENOENT when there is none. */
int storage_sensor_find(storage_t *st, const char *model, const char *serial,
                        storage_sensor_t *out, err_t *err);
/* A page of the sensors, by id (oldest first): at most limit (<= 0: all) from offset (>= 0);
 * out->total counts all sensors. Caller frees with storage_sensor_list_free. */
int storage_sensor_list(storage_t *st, int limit, int offset, storage_sensor_list_t *out,
                        err_t *err);
void storage_sensor_free(storage_sensor_t *s);
void storage_sensor_list_free(storage_sensor_list_t *l);

/* ---- scans -------------------------------------------------------------------------------- */

/* A raster scan around one pixel of interest (POI). The sub-frame read at every point is
 * sub_px x sub_px pixels centred on the POI (sub_px odd): sub-frame pixel (i, j) is sensor pixel
 * (poi_col - h + i, poi_row - h + j) with h = (sub_px - 1) / 2. Pixels of the sub-frame are named
 * by their offset (dcol, drow) = (i - h, j - h) from the POI, so (0, 0) is the POI itself. */
typedef struct storage_scan {
    int64_t id, sensor_id;
    int poi_col, poi_row;    /* POI in sensor coordinates (column, row) */
    double wavelength_um, na, spot_radius_um; /* optics; R of eq. 1 */
    int area_px;             /* the raster covers area_px x area_px pixels around the POI */
    double step_um;          /* raster step */
    int sub_px;              /* m: sub-frame m x m, odd */
    int frames;              /* k: sub-frames captured per point */
    double exposure_us;      /* nominal exposure (each point records its own) */
    int points_total;        /* raster points (set by the caller who plans the raster) */
    /* set by storage */
    storage_state_t state;
    int points_done;         /* points stored (storage_frame_put keeps it) */
    char *error;             /* NULL unless failed */
    int64_t created_ms, started_ms, finished_ms;
    char *job_params;        /* storage_scan_list only: the params of the scan's newest scan job
                                (JSON text; NULL from the other reads, or with no job) */
} storage_scan_t;

typedef struct storage_scan_list {
    storage_scan_t *items;
    size_t n;
    int64_t total;           /* rows matching the filter, whatever limit/offset */
} storage_scan_list_t;

/* Stores a scan in state queued (id, state, progress, error and times of sc are ignored).
 * -ENOENT for an unknown sensor, -EINVAL for settings out of range or a sub-frame that does not
 * fit on the sensor. */
int storage_scan_create(storage_t *st, const storage_scan_t *sc, int64_t *id, err_t *err);
/* Creates the scan and enqueues its scan job (params_json, linked to the scan) in ONE
 * transaction: either both exist afterwards or neither. */
int storage_scan_submit(storage_t *st, const storage_scan_t *sc, const char *params_json,
                        int64_t *scan_id, int64_t *job_id, err_t *err);
int storage_scan_get(storage_t *st, int64_t id, storage_scan_t *out, err_t *err);
/* Scans newest first, filtered by sensor (0: any) and state (STORAGE_ANY: any); limit <= 0: no
 * limit. out->total counts every match. Each item also carries its scan job's params
 * (job_params), read in the same statement. Caller frees with storage_scan_list_free. */
int storage_scan_list(storage_t *st, int64_t sensor_id, int state, int limit, int offset,
                      storage_scan_list_t *out, err_t *err);
/* Sets the state (and the error text, NULL to clear). Entering running stamps started_ms the
 * first time; entering done/failed/cancelled stamps finished_ms. -ENOENT for an unknown scan. */
int storage_scan_set_state(storage_t *st, int64_t id, storage_state_t state, const char *error,
                           err_t *err);
/* Resumes a failed scan (after a storage or camera fault): the scan and its latest
 * scan job are queued again in one transaction, keeping every stored point, the setup and the
 * job's progress (the job's error, end time and attempts are cleared); the scan worker continues
 * after the last stored point. *job_id: that job. -ENOENT unknown scan; -ESTALE when the scan
 * or its job is not failed. */
int storage_scan_resume(storage_t *st, int64_t id, int64_t *job_id, err_t *err);
/* The end of a scan whose points are all stored, in one transaction (as three, a user's
 * re-fit queued between the scan becoming done and the automatic fit made the automatic fit be
 * skipped): the scan becomes done, the automatic fit (fit_params_json) is queued for it, and its
 * running scan job job_id ends as done. The fit is queued when the scan becomes done here, or when
 * it was done already (an older ipsd stopped between the steps) and has no fit job yet; *fit_job_id
 * gets its id, 0 when none was queued. -ECANCELED / -ESTALE / -ENOENT as storage_job_finish (and
 * -ENOENT for an unknown scan), -EINVAL when fit_params_json is not JSON: then nothing is stored.
 */
int storage_scan_finish(storage_t *st, int64_t scan_id, int64_t job_id, const char *fit_params_json,
                        int64_t *fit_job_id, err_t *err);
void storage_scan_free(storage_scan_t *sc);
void storage_scan_list_free(storage_scan_list_t *l);

/* The scan's setup: what the scan procedure found before the raster (centre, exposure, sensor
 * constants), as JSON text the caller defines (schema 2). A resumed raster and the extraction of
 * a pixel's response need it. set: -EINVAL when not valid JSON, -ENOENT for an unknown scan.
 * get: *json is a malloc'ed copy owned by the caller (free()), NULL when none is stored yet. */
int storage_scan_set_setup(storage_t *st, int64_t id, const char *json, err_t *err);

/* The scan's points_total set to total (1..SCAN_MAX_POINTS, at least its points_done): an
 * adaptive scan knows its count only when it stops. -ENOENT unknown scan, -EINVAL a total out of
 * range or below the points stored. */
int storage_scan_set_points_total(storage_t *st, int64_t id, int total, err_t *err);
int storage_scan_get_setup(storage_t *st, int64_t id, char **json, err_t *err);

/* ---- frames: one row per scan point ------------------------------------------------------- */

typedef struct storage_frame {
    int64_t scan_id;
    int point_index;         /* 0 .. points_total - 1, in raster order */
    double stage_x_um, stage_y_um, stage_z_um; /* stage position at this point */
    double exposure_us;
    int frames, sub_px;      /* k and m; must equal the scan's */
    uint16_t *raw;           /* raw_count*m*m raw sub-frames, frame after frame (raw_first
                                first), each row-major y then x; all k from storage_frame_get */
    double *mean;            /* m*m mean of the k sub-frames (DN), row-major y then x */
    int64_t captured_ms;     /* set by storage */
    int raw_first, raw_count; /* read back: the frames raw holds (0 and k but for _get_part) */
    /* schema 10, each k long or NULL (not recorded: older rows; no ids from the camera): each
     * frame's start of exposure on the camera backend's clock (ns), and the camera's own frame
     * ids (GigE Vision block ids) */
    int64_t *timestamps_ns;
    uint64_t *camera_frame_ids;
} storage_frame_t;

/* Stores one point and advances the scan's points_done, in one transaction. The scan must be
 * running: -ECANCELED when it was cancelled, -ESTALE in any other state. -EEXIST when the point
 * is stored already (the stored row is left as it was), -EINVAL for an index out of range or
 * non-finite positions. */
int storage_frame_put(storage_t *st, const storage_frame_t *f, err_t *err);
/* One point's frames; caller frees with storage_frame_free. -ENOENT when not stored. */
int storage_frame_get(storage_t *st, int64_t scan_id, int point_index, storage_frame_t *out,
                      err_t *err);
/* The same with only raw frames first .. first + count - 1 read (the point's other raw frames
 * are not loaded: a point can store hundreds of megabytes); 0 <= first, count and first + count
 * <= k, else -ERANGE. */
int storage_frame_get_part(storage_t *st, int64_t scan_id, int point_index, int first, int count,
                           storage_frame_t *out, err_t *err);
/* For resume: *last = highest stored point index (-1 when none) and *count = points stored.
 * The scan writer stores points in raster order, so it resumes at *last + 1 (and count ==
 * last + 1 says nothing is missing). -ENOENT for an unknown scan. */
int storage_frame_last(storage_t *st, int64_t scan_id, int *last, int *count, err_t *err);
void storage_frame_free(storage_frame_t *f);
/* Bytes one point of k frames of m x m pixels stores (its raw frames, 16 bit, and its mean
 * frame, 64 bit; SQLite's row overhead not counted): what a scan's size is estimated from. */
double storage_frame_bytes(int frames, int sub_px);

/* The response of one sub-frame pixel across all stored points of a scan, in point order: what
 * the fit needs. Arrays of n, owned (storage_raster_free). */
typedef struct storage_raster {
    size_t n;
    int *point_index;
    double *stage_x_um, *stage_y_um;
    double *exposure_us;
    double *mean_dn;         /* the pixel's value in the point's mean frame */
} storage_raster_t;

/* Pixel (dcol, drow) relative to the POI, each in [-h, h] (see storage_scan_t). */
int storage_frame_raster(storage_t *st, int64_t scan_id, int dcol, int drow,
                         storage_raster_t *out, err_t *err);
void storage_raster_free(storage_raster_t *r);

/* Every stored point's whole mean frame (sub_px^2 means, row-major), in point order, in one read:
 * every pixel's response at once (GET /api/scans/{id}/scanfile). Arrays owned
 * (storage_means_free). */
typedef struct storage_means {
    size_t n;
    int sub_px;
    int *point_index;
    double *stage_x_um, *stage_y_um;
    double *mean_dn; /* n * sub_px^2: point k's frame at k * sub_px^2 */
} storage_means_t;

int storage_frame_means(storage_t *st, int64_t scan_id, storage_means_t *out, err_t *err);
void storage_means_free(storage_means_t *m);

/* ---- jobs --------------------------------------------------------------------------------- */

/* ptc: a photon-transfer measurement of a sensor (schema 5), run by the instrument's worker */
typedef enum storage_job_kind {
    STORAGE_JOB_SCAN = 0,
    STORAGE_JOB_FIT = 1,
    STORAGE_JOB_PTC = 2
} storage_job_kind_t;
/* a kind's bit in the mask of storage_job_claim_kinds */
#define STORAGE_JOB_BIT(kind) (1u << (unsigned)(kind))

/* "scan" / "fit" (static), NULL when out of range; parse gives -EINVAL for unknown names. */
const char *storage_job_kind_name(int kind);
int storage_job_kind_parse(const char *name, storage_job_kind_t *out);

typedef struct storage_job {
    int64_t id;
    storage_job_kind_t kind;
    char *params;            /* JSON text */
    storage_state_t state;
    double progress;         /* 0..1 */
    int points_done;
    char *error;             /* NULL unless failed */
    int attempts;            /* times claimed */
    int64_t heartbeat_ms, created_ms, started_ms, finished_ms;
    int64_t scan_id, fit_id; /* links, 0 = none */
    char *fit_ids;           /* a job of every pixel ("pixels" in params): a JSON array of the fits
                              * it stored, in the order stored (fits.job_id); NULL otherwise */
    char *bench;             /* the bench whose instrument runs it (a scan or ptc job enqueued by
                              * a named handle); NULL: any ipsd may run it */
    char *claimed_by;        /* the ipsd that claimed it last; NULL: never, or an unnamed one */
} storage_job_t;

typedef struct storage_job_list {
    storage_job_t *items;
    size_t n;
    int64_t total;
} storage_job_list_t;

/* Queues a job (params_json must be valid JSON, else -EINVAL); scan_id links it to a scan (0:
 * none). The row is committed when this returns; *id gets its id. */
int storage_job_enqueue(storage_t *st, storage_job_kind_t kind, const char *params_json,
                        int64_t scan_id, int64_t *id, err_t *err);
/* Atomically takes the oldest queued job of the kind: running, attempts + 1, heartbeat and
 * started_ms stamped. Returns 0 with the job in *out (caller frees with storage_job_free), or 0
 * with out->id == 0 when none is queued. Two handles never get the same job. */
int storage_job_claim(storage_t *st, storage_job_kind_t kind, storage_job_t *out, err_t *err);
/* The same for the oldest queued job of any of the kinds (a mask of STORAGE_JOB_BIT): the
 * instrument's worker takes scan and ptc jobs in the order they were queued. */
int storage_job_claim_kinds(storage_t *st, unsigned kinds, storage_job_t *out, err_t *err);
/* A running job reports it is alive: heartbeat, progress (0..1) and points done. -ECANCELED
 * when the job was cancelled (the worker should stop), -ESTALE when it is no longer running for
 * another reason (e.g. requeued as stale), -ENOENT for an unknown job. */
int storage_job_heartbeat(storage_t *st, int64_t id, double progress, int points_done,
                          err_t *err);
/* Ends a running job as STORAGE_DONE (progress 1) or STORAGE_FAILED (with error text).
 * -ECANCELED / -ESTALE / -ENOENT as storage_job_heartbeat; the job is then left as it is. */
int storage_job_finish(storage_t *st, int64_t id, storage_state_t state, const char *error,
                       err_t *err);
/* Cancels a queued or running job; *changed = 1 if it did, 0 if the job had already ended.
 * Cancelling a scan job also cancels its scan if that is queued or running (same transaction),
 * so the scan writer's next storage_frame_put returns -ECANCELED. -ENOENT for an unknown job. */
int storage_job_cancel(storage_t *st, int64_t id, int *changed, err_t *err);
/* Gives a running job back to the queue (graceful shutdown): queued again, heartbeat cleared, the
 * claim not counted in attempts. -ECANCELED / -ESTALE / -ENOENT as storage_job_heartbeat. */
int storage_job_release(storage_t *st, int64_t id, err_t *err);
int storage_job_get(storage_t *st, int64_t id, storage_job_t *out, err_t *err);
/* Jobs newest first, filtered by kind and state (STORAGE_ANY: any) and scan (0: any). */
int storage_job_list(storage_t *st, int kind, int state, int64_t scan_id, int limit, int offset,
                     storage_job_list_t *out, err_t *err);
/* storage_job_requeue_claimed: the same for the jobs one claimant left running (NULL: anyone's):
 * an ipsd that shares the database with others requeues only its own at start-up, and another
 * instance's once their lease (stale_ms without a heartbeat) has run out.
 * For start-up after a crash: every running job whose heartbeat is at least stale_ms old (0:
 * every running job) goes back to queued, unless it has been claimed max_attempts times already
 * (max_attempts > 0), in which case it fails with an "abandoned" error. Counts in *requeued and
 * *failed (either may be NULL). Scans are not touched: the scan job's worker resumes its scan. */
int storage_job_requeue_claimed(storage_t *st, const char *claimant, int64_t stale_ms,
                                int max_attempts, int *requeued, int *failed, err_t *err);
int storage_job_requeue_stale(storage_t *st, int64_t stale_ms, int max_attempts, int *requeued,
                              int *failed, err_t *err);
void storage_job_free(storage_job_t *j);
void storage_job_list_free(storage_job_list_t *l);

/* ---- fits and calibrations ---------------------------------------------------------------- */

typedef struct storage_fit {
    int64_t id, scan_id;     /* scan_id 0: a fit of an uploaded scan file (then dcol = drow = 0) */
    int dcol, drow;          /* fitted sub-frame pixel, relative to the POI */
    char *noise_model;       /* "paper", "shot+read" (fit_noise_name) */
    int best_r_aic, best_r_bic; /* 0: none */
    double f_value, p_value; /* F-test; NaN when there was none */
    char *result;            /* the whole fit result, JSON text */
    int64_t created_ms;
    /* read by get and list, ignored on input: the map the fit offers as its pixel's calibration
     * (kept with the fit, promotable) and that pixel's current calibration */
    int64_t map_sensor_id;   /* 0: the fit offers no map (none admissible, or no sensor pixel) */
    int map_col, map_row, map_r;
    int map_kind;            /* which map it is (a storage_map_t) */
    int64_t pixel_calib_id;  /* the current calibration of that pixel, 0: none */
    int64_t pixel_calib_fit_id; /* the fit it came from (== id: this fit is the calibration) */
} storage_fit_t;

typedef struct storage_fit_list {
    storage_fit_t *items;
    size_t n;
    int64_t total;
} storage_fit_list_t;

/* Which map of its fit a calibration holds (the column map of fit_maps and calibrations, schema
 * 7; 'kriged' schema 8): the recommended r's own least-squares map, its detail shrunk toward
 * r - 1 (fit/shrink.h), or the kriged map on its fine grid (fit/krige.h; r is then that grid). */
typedef enum storage_map {
    STORAGE_MAP_RECOMMENDED = 0,
    STORAGE_MAP_SHRUNK = 1,
    STORAGE_MAP_KRIGED = 2,
} storage_map_t;
#define STORAGE_MAP_WORDS "recommended, shrunk or kriged"
/* The map's word ("recommended", "shrunk", "kriged"). */
const char *storage_map_name(storage_map_t m);
/* The map of a word, -1 when it names none. */
int storage_map_parse(const char *word);

/* One IPS map of one sensor pixel with its provenance. */
typedef struct storage_calib {
    int64_t id, sensor_id;
    int pixel_col, pixel_row; /* sensor coordinates */
    int r;                   /* map is r x r, 1..64 */
    double *S, *S_err;       /* r*r each, row-major y then x, S mean 1 */
    double I0, chi2_red;     /* NaN: unknown */
    char *status;            /* fit status word ("ok", ...) */
    int64_t scan_id, fit_id; /* provenance, 0: none */
    char *noise_model;
    double wavelength_um, na, spot_radius_um; /* optics of the scan; NaN: unknown */
    char *software_version;  /* NULL on input: this build's IPSD_VERSION */
    int64_t created_ms;      /* set by storage */
    int64_t superseded_by;   /* 0: current; else the id of the newer calibration */
    /* provenance of the change (schema 3): set by storage on input */
    int64_t supersedes;      /* the calibration this one replaced as current, 0: none */
    /* who made it current and why, declared names (there is no authentication); NULL on input:
     * "ipsd" and "no reason given"; an empty string is -EINVAL */
    char *by;
    char *reason;
    storage_map_t map; /* which map of its fit (schema 7, column map; storage_map_t) */
    double *S_res; /* r*r or NULL (not known): the map's resolution error (schema 7, fit/shrink.h:
                      add in quadrature to S_err) */
    char *map_note; /* NULL, or one sentence on how the map was made when it is not the map its
                       fit asked for (schema 9: no kriged map could be made, and why) */
} storage_calib_t;

typedef struct storage_calib_list {
    storage_calib_t *items;
    size_t n;
    int64_t total;
} storage_calib_list_t;

/* Stores a fit (id/created_ms ignored). If calib is not NULL, keeps its map and pixel as the map
 * the fit offers (promotable later, storage_calib_promote) and, when promote is 1, stores it as
 * the new current calibration of its pixel too, with fit_id set to the new fit (and scan_id to
 * the fit's when 0) and calib's by / reason. If job_id > 0, links that job to the fit. All in one
 * transaction. *fit_id / *calib_id (either may be NULL) get the new ids (calib_id 0: none). */
int storage_fit_store(storage_t *st, const storage_fit_t *fit, const storage_calib_t *calib,
                      int promote, int64_t job_id, int64_t *fit_id, int64_t *calib_id,
                      err_t *err);
/* storage_fit_store of a fit job's result (job_id > 0) that also ends the job as done, in the
 * same transaction: a crash leaves either nothing (the job is still running and runs again at
 * the next start) or the fit, its map, its calibration and the job's `done` together, so a job
 * never stores two fits. The job must be running: -ECANCELED (cancelled meanwhile) / -ESTALE /
 * -ENOENT as storage_job_finish, and then nothing is stored. */
int storage_fit_store_done(storage_t *st, const storage_fit_t *fit, const storage_calib_t *calib,
                           int promote, int64_t job_id, int64_t *fit_id, int64_t *calib_id,
                           err_t *err);
/* One unit of a job that stores several fits (every pixel a scan covers, one fit per pixel):
 * storage_fit_store with the job's count of done units
 * (points_done) moved from done_before to done_before + 1 and its progress to that fraction of
 * total, and on the last unit (done_before + 1 == total) the job's end as done, all in one
 * transaction; the job is linked to the fit: its fit_id becomes the unit's fit, and the fit's
 * job_id the job, so element k of the job's fit_ids (storage_job_t) is unit k's fit. So a crash
 * leaves each unit stored once or not at all, and a rerun of the job resumes at unit
 * points_done. The job must be running with exactly done_before units done:
 * -ESTALE (another count: that unit was stored already, or not running), -ECANCELED, -ENOENT, and
 * then nothing is stored. */
int storage_fit_store_unit(storage_t *st, const storage_fit_t *fit, const storage_calib_t *calib,
                           int promote, int64_t job_id, int done_before, int total,
                           int64_t *fit_id, int64_t *calib_id, err_t *err);
/* storage_fit_store with promote = 1 (the fit's map becomes the calibration). */
int storage_fit_put(storage_t *st, const storage_fit_t *fit, const storage_calib_t *calib,
                    int64_t job_id, int64_t *fit_id, int64_t *calib_id, err_t *err);
/* Makes the map fit_id offers the current calibration of its pixel: a new calibration row (the
 * fit's map, optics and software version) superseding the current one, recorded as done by `by`
 * for `reason` (NULL: the defaults of storage_calib_t). One transaction. -ENOENT for an unknown
 * fit, -ENODATA when the fit offers no map, -EALREADY when the pixel's current calibration is
 * already this fit's (*calib_id then gets its id and nothing is written). */
int storage_calib_promote(storage_t *st, int64_t fit_id, const char *by, const char *reason,
                          int64_t *calib_id, err_t *err);
int storage_fit_get(storage_t *st, int64_t id, storage_fit_t *out, err_t *err);
/* Fits of one scan, newest first. */
int storage_fit_list(storage_t *st, int64_t scan_id, int limit, int offset, storage_fit_list_t *out,
                     err_t *err);
void storage_fit_free(storage_fit_t *f);
void storage_fit_list_free(storage_fit_list_t *l);

/* Stores a calibration as the current one of its sensor pixel; the previous current one (if any)
 * gets superseded_by = the new id in the same transaction and stays queryable. -ENOENT for an
 * unknown sensor/scan/fit, -EINVAL for a pixel outside the sensor or a bad map. */
int storage_calib_put(storage_t *st, const storage_calib_t *c, int64_t *id, err_t *err);
int storage_calib_get(storage_t *st, int64_t id, storage_calib_t *out, err_t *err);
/* The current calibration of a sensor pixel; -ENOENT when it has none. */
int storage_calib_current(storage_t *st, int64_t sensor_id, int pixel_col, int pixel_row,
                          storage_calib_t *out, err_t *err);
/* Every calibration of a sensor pixel, newest first (the current one first). */
int storage_calib_history(storage_t *st, int64_t sensor_id, int pixel_col, int pixel_row,
                          storage_calib_list_t *out, err_t *err);

typedef struct storage_calib_filter {
    int64_t sensor_id;       /* 0: any */
    const char *model;       /* sensor model; NULL: any */
    int col_min, col_max;    /* inclusive pixel range; -1: unbounded */
    int row_min, row_max;
    int64_t since_ms;        /* created at or after; 0: any */
    const char *status;      /* NULL: any */
    int current_only;        /* 1: leave out superseded calibrations */
} storage_calib_filter_t;

/* A filter that matches everything (current_only = 0). */
storage_calib_filter_t storage_calib_filter_default(void);
/* Calibrations across sensors, newest first, with out->total counting every match. */
int storage_calib_search(storage_t *st, const storage_calib_filter_t *f, int limit, int offset,
                         storage_calib_list_t *out, err_t *err);
void storage_calib_free(storage_calib_t *c);
void storage_calib_list_free(storage_calib_list_t *l);

/* ---- photon-transfer measurements (storage_ptc.c) ------------------------------------------ */

/* One EMVA 1288 measurement of a sensor (fit/ptc.h): its figures, and the whole report as JSON
 * (the `ips ptc` document). Every measurement is kept; the newest is the sensor's measured
 * constants. */
typedef struct storage_ptc {
    int64_t id;
    int64_t sensor_id;
    double gain_e_per_dn, read_noise_e; /* > 0, >= 0 */
    double dark_dn, saturation_dn, linearity_error_pct; /* NaN: not measured */
    char *result;       /* JSON text */
    int64_t job_id;     /* the job that measured it; 0: none */
    int64_t created_ms;
} storage_ptc_t;

typedef struct storage_ptc_list {
    storage_ptc_t *items;
    size_t n;
} storage_ptc_list_t;

/* Stores a measurement (one transaction). -ENOENT for an unknown sensor or job, -EINVAL for a
 * gain or read noise out of range or result not JSON. */
int storage_ptc_put(storage_t *st, const storage_ptc_t *p, int64_t *id, err_t *err);
/* storage_ptc_put of a ptc job's result (p->job_id > 0) that also ends the job as done, in one
 * transaction: a crash leaves either nothing (the job is still running and runs again) or both,
 * so a job never stores two measurements. The job must be running: -ECANCELED (cancelled
 * meanwhile) / -ESTALE / -ENOENT as storage_job_finish, and then nothing is stored. */
int storage_ptc_store_done(storage_t *st, const storage_ptc_t *p, int64_t *id, err_t *err);
/* One measurement by id; -ENOENT when unknown. Free with storage_ptc_free. */
int storage_ptc_get(storage_t *st, int64_t id, storage_ptc_t *out, err_t *err);
/* The sensor's measurements, newest first (at most limit; <= 0: all); none is not an error. */
int storage_ptc_history(storage_t *st, int64_t sensor_id, int limit, storage_ptc_list_t *out,
                        err_t *err);
void storage_ptc_free(storage_ptc_t *p);
void storage_ptc_list_free(storage_ptc_list_t *l);

/* ---- online backup (storage_backup.c) ----------------------------------------------------- */

/* What a backup wrote. */
typedef struct storage_backup_info {
    int64_t bytes;       /* size of the backup file */
    int pages;           /* database pages copied */
    int schema_version;  /* the copy's user_version */
    char integrity[256]; /* "ok", or the first problem PRAGMA integrity_check found */
} storage_backup_info_t;

/* Called between the steps of a backup with the pages left and the total; a nonzero return
 * stops the backup (-ECANCELED). */
typedef int (*storage_backup_step_fn)(void *ctx, int remaining, int total);

/* Copies the database of st, as it was when the backup began, to the new file dest with SQLite's
 * online backup API, pages_per_step pages at a time (<= 0: 256). st holds one read transaction
 * throughout (a WAL snapshot): other connections and processes keep writing meanwhile and their
 * writes are not in the copy (nor do they restart it); only checkpoints cannot go past the
 * snapshot until it ends. The copy is written as dest.part, switched to journal_mode DELETE (one
 * self-contained file), checked (PRAGMA integrity_check), synced and renamed to dest, so dest
 * exists only complete. step (NULL: none) runs between steps, with st's connection idle.
 * -EEXIST when dest or dest.part exists, -ECANCELED when step stopped it, -EIO when the copy
 * failed its integrity check (dest is then not made), -ENOSPC, -EIO; info is filled on success. */
int storage_backup(storage_t *st, const char *dest, int pages_per_step,
                   storage_backup_step_fn step, void *ctx, storage_backup_info_t *info,
                   err_t *err);

#endif
