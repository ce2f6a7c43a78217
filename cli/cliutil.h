/* cliutil.h: what every `ips` command shares: the one-line error convention (exit 2 for bad
 * input, 1 for other failures). Number parsing, option parsing and the clock are base/'s. */
#ifndef IPSD_CLI_CLIUTIL_H
#define IPSD_CLI_CLIUTIL_H

#define CLI_EXIT_FAILURE 1 /* the tool failed (out of memory, I/O) */
#define CLI_EXIT_USAGE 2   /* bad input: arguments, options, files */

/* Prints "ips CMD: message" as one line on stderr (newlines in the message become spaces) and
 * returns code, so commands can `return cli_fail(...)`. */
int cli_fail(int code, const char *cmd, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Exit code for a negative error code from a library: 1 for -ENOMEM and -EIO, else 2 (the
 * libraries return -EINVAL and the like for input they cannot use). */
int cli_exit_code(int rc);

#endif
