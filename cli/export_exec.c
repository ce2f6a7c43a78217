/* export_exec.c: the ips commands that need cfitsio run a companion executable beside ips (found
 * through /proc/self/exe) with the same arguments: `ips export` runs ips-export, `ips import-fits`
 * runs ips-import-fits. Why second programs: cli/CMakeLists.txt. */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "cliutil.h"
#include "commands.h"

/* Replaces this process by the program prog beside ips; argv[0] stays the command's name (cmd),
 * which the companion's messages use. Returns only on failure. */
static int exec_beside(const char *prog, const char *cmd, char **argv)
{
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) return cli_fail(1, cmd, "cannot find ips's own path: %s", strerror(errno));
    self[n] = 0;
    char *slash = strrchr(self, '/');
    char path[PATH_MAX + 32];
    snprintf(path, sizeof path, "%.*s/%s", slash ? (int)(slash - self) : 1, slash ? self : ".",
             prog);
    execv(path, argv);
    return cli_fail(1, cmd, "cannot run %s (installed beside ips?): %s", path, strerror(errno));
}

int cmd_export_exec(int argc, char **argv)
{
    (void)argc;
    return exec_beside("ips-export", "export", argv);
}

int cmd_import_fits_exec(int argc, char **argv)
{
    (void)argc;
    return exec_beside("ips-import-fits", "import-fits", argv);
}
