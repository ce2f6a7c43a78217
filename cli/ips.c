/* ips.c: the `ips` command-line tool over fit/ and instrument/: dispatch to the commands of
 * commands.h. */
#include <malloc.h>
#include <stdio.h>
#include <string.h>

#include "base/heap_huge.h"
#include "cliutil.h"
#include "commands.h"

/* The heap ips keeps on huge pages: the 41 x 41 sweep over r = 1..16 (bench/speed.sh) peaks at
 * 26 MB; only what is touched is used. */
#define HEAP_HUGE_MB 64

static const struct command {
    const char *name;
    int (*run)(int argc, char **argv);
    const char *summary;
} commands[] = {
    {"fit", cmd_fit, "fit a scan file: model selection over r, the map, F-test, Wiener"},
    {"box", cmd_box, "integral of the unit-peak Airy spot over a rectangle, with error bound"},
    {"bench", cmd_bench, "design-matrix accuracy against run time, and the speed of a full fit"},
    {"simulate", cmd_simulate, "a scan by the simulated bench, written as a scan file"},
    {"export", cmd_export_exec, "IPS maps (calibrations, fits) as a FITS file"},
    {"import-fits", cmd_import_fits_exec, "a pixel's scan file from a lab's FITS scan cube"},
    {"jitter", cmd_jitter, "the flux error a pixel's map adds under pointing jitter"},
    {"ptc", cmd_ptc, "photon transfer (EMVA 1288): gain, read noise, saturation on the bench"},
};

static void usage(FILE *f)
{
    fprintf(f, "usage: ips COMMAND [ARGS]   (ips COMMAND --help for its options)\n\n"
               "Intra-pixel sensitivity maps by the method of Mahato et al.\n\ncommands:\n");
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        fprintf(f, "  %-9s %s\n", commands[i].name, commands[i].summary);
    fprintf(f, "\nExit status: 0 success, 1 failure, 2 bad input (one line on stderr).\n");
}

int main(int argc, char **argv)
{
    /* A fit allocates and frees megabyte buffers per r (design matrix, QR copy); glibc would map
     * each afresh and the process would spend ~10 % of a 41 x 41 sweep in page faults (perf).
     * Serving them from the heap and keeping freed memory there makes later r reuse the pages. */
    mallopt(M_MMAP_THRESHOLD, 256 << 20);
    mallopt(M_TRIM_THRESHOLD, 512 << 20);
    /* ... and those pages huge (base/heap_huge.h): page faults were a third of a fit's CPU time
     * on a virtual machine (6,666 of them in the 41 x 41 sweep, 14 us each) */
    heap_huge_pages((size_t)HEAP_HUGE_MB << 20);
    /* one arena, so that the sweep's threads (ips fit --threads) allocate from that heap too: a
     * thread's own arena is mapped afresh, 4 KiB at a time; they allocate a few blocks per r */
    mallopt(M_ARENA_MAX, 1);
    if (argc < 2) {
        usage(stderr);
        return CLI_EXIT_USAGE;
    }
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 ||
        strcmp(argv[1], "help") == 0) {
        usage(stdout);
        return 0;
    }
    if (strcmp(argv[1], "--version") == 0) {
        printf("ips %s\n", IPSD_VERSION);
        return 0;
    }
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        if (strcmp(argv[1], commands[i].name) == 0) return commands[i].run(argc - 1, argv + 1);
    return cli_fail(CLI_EXIT_USAGE, NULL, "unknown command '%s' (see ips --help)", argv[1]);
}
