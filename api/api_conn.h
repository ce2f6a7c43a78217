/* api_conn.h (internal to api/): the HTTP connections ipsd has open, each with the deadline its
 * current request must be read by. libmicrohttpd has only an idle timeout, which a client
 * trickling a header line every few seconds never hits, so such a client could hold a
 * connection for ever; here a reaper thread shuts down the socket of any connection whose
 * request (headers and body) is not read within --request-timeout seconds of the connection's
 * start or of its previous request's end. A request being answered (an event stream included)
 * has no deadline. */
#ifndef IPSD_API_API_CONN_H
#define IPSD_API_API_CONN_H

#include <microhttpd.h>
#include <stddef.h>
#include <stdint.h>

typedef struct api_conns api_conns_t;

/* Starts the tracker (and its reaper thread when timeout_s > 0). NULL when out of memory. */
api_conns_t *api_conns_open(double timeout_s);
/* Stops the reaper and frees the tracker (after the daemon has stopped). */
void api_conns_close(api_conns_t *cs);

/* libmicrohttpd's MHD_OPTION_NOTIFY_CONNECTION callback (cls: the api_conns_t). */
void api_conns_notify(void *cls, struct MHD_Connection *conn, void **socket_context,
                      enum MHD_ConnectionNotificationCode code);

/* The connection's request is being answered (no deadline), or has ended (its deadline starts
 * again for the next request). */
void api_conn_answering(struct MHD_Connection *conn, int answering);

/* Connections open now, and connections shut down for missing their deadline so far. */
void api_conns_counts(api_conns_t *cs, size_t *open, uint64_t *reaped);

#endif
