/* api_backup.c: POST /api/backup: an online backup of the database into the server's
 * --backup-dir (srv_backup), answered with the file's name, size, page count, schema version
 * and integrity check once it is written and checked. The copy runs in the request's HTTP
 * thread (a 1 GB database takes seconds); writers are not held up meanwhile (docs/operations.md).
 */
#include <errno.h>

#include "api_int.h"

void api_h_backup(api_req_t *q)
{
    /* no member is known: a body, when one comes, is an empty object (a misspelt option is
     * refused rather than ignored) */
    if (q->body_len) {
        static const char *const keys[] = {NULL};
        json_t *o = api_body_object(q);
        int bad = !o || api_no_unknown(q, o, "", keys);
        json_decref(o);
        if (bad) return;
    }
    storage_t *st = api_db(q);
    if (!st) return;
    char name[128];
    storage_backup_info_t info;
    err_t err = {{0}};
    int ret = srv_backup(q->srv, st, name, sizeof name, &info, &err);
    switch (ret) {
    case 0:
        api_reply_json(q, 201,
                       json_pack("{s:s, s:I, s:i, s:i, s:s}", "file", name, "bytes",
                                 (json_int_t)info.bytes, "pages", info.pages, "schema_version",
                                 info.schema_version, "integrity", info.integrity));
        return;
    case -ENOTSUP:
        api_error(q, 409, "backups_off", NULL, "%s", err.msg);
        return;
    case -EBUSY:
        api_error(q, 409, "backup_running", NULL, "%s", err.msg);
        return;
    case -ENOSPC:
        api_error(q, 507, "insufficient_storage", NULL, "%s", err.msg);
        return;
    default:
        api_error_rc(q, ret, NULL, err.msg);
    }
}
