/* srv_tools.c: ipsd's one-shot modes, run instead of the server: --hash-token prints the line a
 * token file may hold instead of the token (srv_token.h), --backup OUT makes an online backup of
 * --db (storage_backup) that may run while an ipsd serves the same database, --list-cameras
 * prints the cameras of every camera backend (the --bench values that name them). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "instrument/cam.h"
#include "server/srv_token.h"
#include "srv_int.h"

int srv_tool_list_cameras(void)
{
    /* the simulated bench is always there; then each real backend's cameras, one a line:
     * the --bench value, vendor, model, serial, tab-separated ("-" unknown) */
    printf("sim\tipsd\tsimulated bench\t-\n");
    for (const char *const *b = cam_backends(); *b; b++) {
        if (strcmp(*b, "sim") == 0) continue;
        cam_info_t *l = NULL;
        size_t n = 0;
        err_t err = {{0}};
        if (cam_list(*b, &l, &n, &err)) {
            fprintf(stderr, "ipsd: --list-cameras: %s: %s\n", *b, err.msg);
            continue;
        }
        for (size_t i = 0; i < n; i++)
            printf("%s:%s\t%s\t%s\t%s\n", *b, l[i].id, l[i].vendor[0] ? l[i].vendor : "-",
                   l[i].model[0] ? l[i].model : "-", l[i].serial[0] ? l[i].serial : "-");
        if (n == 0) fprintf(stderr, "ipsd: --list-cameras: %s: no camera found\n", *b);
        free(l);
    }
    return fflush(stdout) == 0 ? 0 : 1;
}

int srv_tool_hash_token(void)
{
    char buf[1024];
    size_t n = fread(buf, 1, sizeof buf - 1, stdin);
    buf[n] = 0;
    char *s = buf, *e = buf + strcspn(buf, "\n"); /* the first line */
    while (*s == ' ' || *s == '\t' || *s == '\r')
        s++;
    while (e > s && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\r'))
        e--;
    int ok = e > s && n < sizeof buf - 1;
    for (const char *p = s; ok && p < e; p++)
        ok = (unsigned char)*p > 0x20 && (unsigned char)*p < 0x7f;
    char line[SRV_TOKEN_HASH_LINE];
    if (ok) srv_token_hash_line(s, (size_t)(e - s), line);
    explicit_bzero(buf, sizeof buf);
    if (!ok) {
        fprintf(stderr, "ipsd: --hash-token: stdin's first line must be a token: 1..1022 "
                        "printable ASCII characters without spaces\n");
        return 2;
    }
    printf("%s\n", line);
    return 0;
}

int srv_tool_backup(const srv_config_t *cfg)
{
    struct stat sb;
    if (storage_is_postgres(cfg->db_path)) {
        fprintf(stderr, "ipsd: --backup copies an SQLite database; a PostgreSQL database is "
                        "backed up with pg_dump (docs/operations.md)\n");
        return 2;
    }
    if (stat(cfg->db_path, &sb) != 0) { /* storage_open would create an empty one */
        fprintf(stderr, "ipsd: --backup: no database %s: %s\n", cfg->db_path, strerror(errno));
        return 2;
    }
    storage_t *st = NULL;
    storage_backup_info_t info;
    err_t err = {{0}};
    /* read-only: a backup taken with a newer ipsd before an upgrade must not migrate the
     * database under the old server, nor write anything into a file that is not ipsd's */
    int ret = storage_open_readonly(cfg->db_path, &st, &err);
    if (ret) {
        fprintf(stderr, "ipsd: --backup: %s\n", err.msg);
        return ret == -EIO || ret == -ENOMEM ? 1 : 2;
    }
    ret = storage_backup(st, cfg->backup_out, 0, NULL, NULL, &info, &err);
    storage_close(st);
    if (ret) {
        fprintf(stderr, "ipsd: %s\n", err.msg); /* "backup: ..." */
        return ret == -EEXIST ? 2 : 1;
    }
    printf("%s: %lld bytes, %d pages, schema %d, integrity %s\n", cfg->backup_out,
           (long long)info.bytes, info.pages, info.schema_version, info.integrity);
    return 0;
}

int srv_tool_db_copy(const srv_config_t *cfg)
{
    struct stat sb;
    if (!storage_is_postgres(cfg->copy_from) && stat(cfg->copy_from, &sb) != 0) {
        /* storage_open would create an empty one */
        fprintf(stderr, "ipsd: --db-copy: no database %s: %s\n", cfg->copy_from, strerror(errno));
        return 2;
    }
    storage_t *from = NULL, *to = NULL;
    storage_copy_info_t info;
    err_t err = {{0}};
    int ret = storage_open(cfg->copy_from, &from, &err);
    if (!ret) ret = storage_open(cfg->copy_to, &to, &err);
    if (!ret) ret = storage_copy(from, to, cfg->bench_name, &info, &err);
    storage_close(from);
    storage_close(to);
    if (ret) {
        fprintf(stderr, "ipsd: --db-copy: %s\n", err.msg);
        return ret == -EINVAL || ret == -ENOTSUP ? 2 : 1;
    }
    printf("ipsd: copied %s into %s: %lld sensor(s) (%lld more found there), %lld scan(s) "
           "(%lld points), %lld job(s), %lld fit(s), %lld calibration(s), %lld ptc; %lld "
           "copied before\n",
           cfg->copy_from, cfg->copy_to, (long long)info.sensors, (long long)info.sensors_matched,
           (long long)info.scans, (long long)info.frames, (long long)info.jobs,
           (long long)info.fits, (long long)info.calibrations, (long long)info.ptc,
           (long long)info.skipped);
    return 0;
}
