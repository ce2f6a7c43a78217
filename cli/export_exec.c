/* export_exec.c: `ips export ...` runs ips-export, the executable beside ips (found through
 * /proc/self/exe), with the same arguments. Why a second program: cli/CMakeLists.txt. */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "cliutil.h"
#include "commands.h"

int cmd_export_exec(int argc, char **argv)
{
    (void)argc;
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) return cli_fail(1, "export", "cannot find ips's own path: %s", strerror(errno));
    self[n] = 0;
    char *slash = strrchr(self, '/');
    char path[PATH_MAX + 16];
    snprintf(path, sizeof path, "%.*s/ips-export", slash ? (int)(slash - self) : 1,
             slash ? self : ".");
    execv(path, argv); /* argv[0] is "export": the command's name in its messages */
    return cli_fail(1, "export", "cannot run %s (installed beside ips?): %s", path,
                    strerror(errno));
}
