/* outfile.h: an output file named on a command line (`ips simulate -o`, `ips import-fits -o`,
 * `ips export -o`, ...), written without ever replacing what the name is not meant to replace:
 *   - a regular file, or a name that does not exist: written to PATH.tmp (created exclusively,
 *     never through a symbolic link), synced, then renamed over PATH, so PATH is never half
 *     written;
 *   - a symbolic link: the same at the file it points to (the link stays a link); a link to
 *     nothing is refused;
 *   - a FIFO or a character device (/dev/null, a terminal, /dev/full): written in place, never
 *     replaced by a regular file;
 *   - a directory, a block device or a socket: refused.
 * One handle per file; not thread-safe. */
#ifndef IPSD_BASE_OUTFILE_H
#define IPSD_BASE_OUTFILE_H

#include <stdio.h>

#include "base/err.h"

#define OUTFILE_PATH_MAX 4096

typedef struct outfile {
    FILE *f;                      /* write here between outfile_open and _commit / _abort */
    char path[OUTFILE_PATH_MAX];  /* the file written: PATH, or the file its link points to */
    char tmp[OUTFILE_PATH_MAX + 8]; /* PATH.tmp while a regular file is written; "" in place */
} outfile_t;

/* Opens path for writing as above. Returns 0; -EINVAL (err: "PATH is a directory: not
 * written", a link to nothing, PATH.tmp that is not a regular file), -ENAMETOOLONG, or -EIO
 * with err naming the path and the system's reason. *o is zeroed on failure. */
int outfile_open(const char *path, outfile_t *o, err_t *err);

/* Finishes the file: flushed (and for a regular file synced and renamed over its path). 0, or
 * -EIO naming the path and the reason (the disk is full: "No space left on device"), the
 * temporary file then removed. Closes o->f either way. */
int outfile_commit(outfile_t *o, err_t *err);

/* Gives the file up: closed, the temporary file removed (a file written in place keeps what was
 * written). Accepts a zeroed handle. */
void outfile_abort(outfile_t *o);

#endif
