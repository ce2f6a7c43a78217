/* cmd_simulate.c: `ips simulate [options] -o FILE`, a scan by the simulated bench written as a
 * scan file. Placeholder until the simulated instrument lands. */
#include "cliutil.h"
#include "commands.h"

int cmd_simulate(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    return cli_fail(CLI_EXIT_USAGE, "simulate", "not available yet");
}
