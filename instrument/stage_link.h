/* stage_link.h (internal to instrument/): the byte stream a stage controller speaks over, a TCP
 * connection or a serial line (termios, raw 8N1 at the configured baud rate; a pseudo-terminal
 * works the same), carrying LF-terminated ASCII lines. Every wait is bounded by poll(): a
 * controller that stops answering gives -ETIMEDOUT, a closed connection -EIO, never a hang.
 * One handle per thread. */
#ifndef IPSD_INSTRUMENT_STAGE_LINK_H
#define IPSD_INSTRUMENT_STAGE_LINK_H

#include <stddef.h>

#include "base/err.h"
#include "stage_url.h"

typedef struct stage_link stage_link_t;

/* Connects to u's TCP address or opens u's serial device, waiting at most u->timeout_s.
 * Returns 0, -ECONNREFUSED / -ETIMEDOUT / -ENOENT / -EIO (named in err) or -ENOMEM. */
int stage_link_open(const stage_url_t *u, stage_link_t **out, err_t *err);

void stage_link_close(stage_link_t *l);

/* Sends the bytes of line and then LF (line holds no LF). Returns 0, -EIO or -ETIMEDOUT. */
int stage_link_send(stage_link_t *l, const char *line, err_t *err);

/* Reads one line (without its LF; a CR before it is dropped too) into buf of n bytes, waiting at
 * most timeout_s for it. Returns its length, -EIO (closed, or an error), -ETIMEDOUT or
 * -EOVERFLOW (longer than n - 1). */
int stage_link_read_line(stage_link_t *l, char *buf, size_t n, double timeout_s, err_t *err);

/* Whether an error of the calls above leaves the link unusable (-EIO, -ETIMEDOUT, -EOVERFLOW: a
 * reply may still be on its way or half read), so that the backend closes it and reconnects at
 * its next call. */
int stage_link_broken(int ret);

/* Sleeps ms milliseconds (the pause between two status polls of a moving stage). */
void stage_link_pause_ms(int ms);

#endif
