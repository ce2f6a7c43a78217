/* outfile.c: output files that never replace a symbolic link, a FIFO or a device (outfile.h).
 * Writing PATH.tmp and renaming it over PATH keeps a regular file whole, but rename replaces
 * whatever PATH is: a link became a regular file, a FIFO's reader never got the data, and as
 * root `-o /dev/full` replaced the device node. So the name is looked at first (lstat), and
 * only a regular file (or nothing) is replaced by rename. */
#include "base/outfile.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* "PATH: reason" as -EIO (a write that failed is a failure, not bad input). */
static int sys_fail(err_t *err, const char *path)
{
    int e = errno ? errno : EIO;
    return err_set(err, -EIO, "%s: %s", path, strerror(e));
}

static const char *kind(mode_t m)
{
    return S_ISDIR(m) ? "a directory" : S_ISBLK(m) ? "a block device" : S_ISSOCK(m) ? "a socket"
                                                                          : "not a regular file";
}

/* PATH.tmp created exclusively and never through a link; a stale regular PATH.tmp (a crash) is
 * removed once. */
static int open_tmp(outfile_t *o, err_t *err)
{
    for (int attempt = 0; attempt < 2; attempt++) {
        int fd = open(o->tmp, O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
        if (fd >= 0) {
            if ((o->f = fdopen(fd, "wb"))) return 0;
            close(fd);
            unlink(o->tmp);
            return sys_fail(err, o->tmp);
        }
        struct stat sb;
        if (errno != EEXIST || attempt) return sys_fail(err, o->tmp);
        if (lstat(o->tmp, &sb) != 0 || !S_ISREG(sb.st_mode))
            return err_set(err, -EINVAL, "%s exists and is not a regular file: not replaced",
                           o->tmp);
        if (unlink(o->tmp) != 0) return sys_fail(err, o->tmp);
    }
    return sys_fail(err, o->tmp);
}

int outfile_open(const char *path, outfile_t *o, err_t *err)
{
    memset(o, 0, sizeof *o);
    struct stat sb;
    if (strlen(path) >= sizeof o->path) return err_set(err, -ENAMETOOLONG, "path too long: %s", path);
    snprintf(o->path, sizeof o->path, "%s", path);
    int exists = lstat(path, &sb) == 0;
    if (exists && S_ISLNK(sb.st_mode)) {
        char target[PATH_MAX];
        if (!realpath(path, target) || stat(target, &sb) != 0)
            return err_set(err, -EINVAL, "%s is a symbolic link to nothing: not replaced", path);
        if (strlen(target) >= sizeof o->path)
            return err_set(err, -ENAMETOOLONG, "path too long: %s", target);
        snprintf(o->path, sizeof o->path, "%s", target);
    }
    if (exists && (S_ISFIFO(sb.st_mode) || S_ISCHR(sb.st_mode))) {
        int fd = open(o->path, O_WRONLY | O_NOCTTY | O_CLOEXEC);
        if (fd < 0) return sys_fail(err, path);
        if (!(o->f = fdopen(fd, "wb"))) {
            close(fd);
            return sys_fail(err, path);
        }
        return 0;
    }
    if (exists && !S_ISREG(sb.st_mode))
        return err_set(err, -EINVAL, "%s is %s: not written", path, kind(sb.st_mode));
    snprintf(o->tmp, sizeof o->tmp, "%s.tmp", o->path);
    int rc = open_tmp(o, err);
    if (rc) memset(o, 0, sizeof *o);
    return rc;
}

int outfile_commit(outfile_t *o, err_t *err)
{
    int rc = 0;
    errno = 0;
    if (fflush(o->f) != 0) rc = sys_fail(err, o->path);
    if (!rc && o->tmp[0] && fsync(fileno(o->f)) != 0) rc = sys_fail(err, o->path);
    if (fclose(o->f) != 0 && !rc) rc = sys_fail(err, o->path);
    o->f = NULL;
    if (o->tmp[0]) {
        if (!rc && rename(o->tmp, o->path) != 0) rc = sys_fail(err, o->path);
        if (rc) unlink(o->tmp);
        o->tmp[0] = 0;
    }
    return rc;
}

void outfile_abort(outfile_t *o)
{
    if (o->f) fclose(o->f);
    o->f = NULL;
    if (o->tmp[0]) unlink(o->tmp);
    o->tmp[0] = 0;
}
