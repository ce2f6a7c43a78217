/* stage_emu.h: starting and stopping an emulated stage controller (tests/gcs_emulator.py,
 * tests/zaber_emulator.py) from a C test: the emulator runs as a child with its stdin on a pipe
 * (closing it ends the emulator, so no test leaves one running) and says on its first stdout line
 * where it listens ("tcp PORT" or "pty /dev/pts/N"). Header-only, for test_stage_*.c. */
#ifndef IPSD_TEST_STAGE_EMU_H
#define IPSD_TEST_STAGE_EMU_H

#include <stdio.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#ifndef IPSD_PYTHON3
#define IPSD_PYTHON3 "python3"
#endif

typedef struct emu {
    pid_t pid;
    int in;          /* the emulator's stdin: closing it ends the emulator */
    char where[256]; /* "tcp PORT" or "pty /dev/pts/N" */
} emu_t;

/* Starts script with options (NULL-terminated) and reads where it listens. */
static int emu_start_script(emu_t *e, const char *script, const char *const *opts)
{
    int in[2], out[2];
    if (pipe(in) || pipe(out)) return -1;
    const char *argv[32] = {IPSD_PYTHON3, "-B", script};
    int n = 3;
    for (; *opts && n < 31; opts++)
        argv[n++] = *opts;
    argv[n] = NULL;
    e->pid = fork();
    if (e->pid == 0) {
        dup2(in[0], 0);
        dup2(out[1], 1);
        close(in[1]);
        close(out[0]);
        execvp(IPSD_PYTHON3, (char *const *)argv);
        _exit(127);
    }
    close(in[0]);
    close(out[1]);
    e->in = in[1];
    size_t len = 0;
    while (len + 1 < sizeof e->where) { /* the first line: blocks until the emulator is up */
        ssize_t r = read(out[0], e->where + len, 1);
        if (r <= 0 || e->where[len] == '\n') break;
        len++;
    }
    e->where[len] = 0;
    close(out[0]);
    return len > 4 ? 0 : -1;
}

static void emu_stop(emu_t *e)
{
    close(e->in);
    int st;
    waitpid(e->pid, &st, 0);
}

/* The stage string FAMILY:tcp://127.0.0.1:PORT?poll_ms=0[&opts] or FAMILY:serial:DEV?... for e. */
static void emu_url(const emu_t *e, const char *family, const char *opts, char *url, size_t n)
{
    if (strncmp(e->where, "tcp ", 4) == 0)
        snprintf(url, n, "%s:tcp://127.0.0.1:%s?poll_ms=0%s%s", family, e->where + 4,
                 *opts ? "&" : "", opts);
    else
        snprintf(url, n, "%s:serial:%s?baud=115200&poll_ms=0%s%s", family, e->where + 4,
                 *opts ? "&" : "", opts);
}

#endif
