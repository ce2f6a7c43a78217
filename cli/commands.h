/* commands.h: the entry points of the `ips` commands, one per cli/cmd_<name>.c. Each takes the
 * arguments after `ips` (argv[0] is the command name), prints its result on stdout, reports bad
 * input as one line on stderr, and returns the exit code (0, 1 failure, 2 bad input). */
#ifndef IPSD_CLI_COMMANDS_H
#define IPSD_CLI_COMMANDS_H

int cmd_fit(int argc, char **argv);      /* fit a scan file: model selection, map, F-test */
int cmd_box(int argc, char **argv);      /* one box integral of the Airy spot */
int cmd_bench(int argc, char **argv);    /* accuracy against run time, speed figures */
int cmd_simulate(int argc, char **argv); /* a scan by the simulated bench, as a scan file */
int cmd_export(int argc, char **argv);   /* IPS maps as a FITS file (ips-export) */
int cmd_export_exec(int argc, char **argv); /* ips: runs ips-export beside it */
int cmd_import_fits(int argc, char **argv); /* a FITS scan cube as a scan file (ips-import-fits) */
int cmd_import_fits_exec(int argc, char **argv); /* ips: runs ips-import-fits beside it */
int cmd_jitter(int argc, char **argv);   /* jitter photometry with a pixel's map */
int cmd_ptc(int argc, char **argv);      /* photon transfer (EMVA 1288) on the simulated bench */

#endif
