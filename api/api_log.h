/* api_log.h: the request log (internal to api/): one line per request, appended to --access-log
 * FILE or stderr, never the Authorization header nor the query string (where a client could put
 * a secret). A line is written with one write() on an O_APPEND descriptor, so the lines of the
 * HTTP threads never interleave. Thread-safe. */
#ifndef IPSD_API_API_LOG_H
#define IPSD_API_API_LOG_H

#include <microhttpd.h>
#include <time.h>

#include "base/err.h"

/* The log's descriptor from cfg->access_log: "" stderr (2), "off" -1 (no log), else the file
 * opened for appending (created 0640). -errno with err when the file cannot be opened. */
int api_log_open(const char *access_log, int *fd, err_t *err);
void api_log_close(int fd); /* closes a file's descriptor (not stderr's); accepts -1 */

/* Log rotation (SIGHUP): opens access_log again by name and puts the new file behind fd with
 * dup2, which swaps it atomically: a line being written goes whole to the old file or the new,
 * and no HTTP thread ever sees a closed descriptor. 0 (also for stderr and "off": nothing to
 * reopen), or -errno with err, fd then still writing to the old file. */
int api_log_reopen(const char *access_log, int fd, err_t *err);

/* Writes the line of one finished request:
 *   TIME CLIENT METHOD PATH STATUS BYTES MSms[ aborted]
 * TIME UTC ISO 8601 with milliseconds, CLIENT the peer address, PATH percent-encoded where not
 * printable ASCII, STATUS 0 and BYTES '-' when unknown (no reply, a stream), MS the time from
 * the request's headers to the end of its reply; "aborted" when the connection ended early.
 * method and path are written as given: pass them through api_log_escape first (NULL: "-"). */
void api_log_request(int fd, struct MHD_Connection *conn, const char *method, const char *path,
                     unsigned status, long long bytes, const struct timespec *t0, int aborted);

/* The text of a method or path as the log writes it, into out (n bytes; cut with "..."). */
void api_log_escape(const char *in, char *out, size_t n);

#endif
