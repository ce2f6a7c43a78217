/* srv_token.h: ipsd's bearer tokens: the token files of --token (write) and --read-token (read),
 * kept only as SHA-256 digests, and the check of a presented token. A token file holds one token
 * per line (blank lines and lines starting with '#' are skipped, surrounding whitespace trimmed):
 * either the token itself, hashed when read and the plain text wiped, or "sha256:" and the 64
 * hex digits of its digest (so a lab can keep only hashes on disk; `ipsd --hash-token` prints
 * that line). SHA-256 is nettle's (the library GnuTLS, and so libmicrohttpd, stands on).
 * Thread-safe: functions only read what they are given (and the tickets' key, drawn once under
 * pthread_once). */
#ifndef IPSD_SERVER_SRV_TOKEN_H
#define IPSD_SERVER_SRV_TOKEN_H

#include <stddef.h>

#include "base/err.h"
#include "server/srv_config.h"

#define SRV_TOKEN_HASH_LINE 72 /* "sha256:" + 64 hex digits + NUL, rounded up */

/* The SHA-256 digest of n bytes. */
void srv_token_digest(const void *data, size_t n, unsigned char out[SRV_TOKEN_DIGEST]);

/* "sha256:HEX" of the token's n bytes into out. */
void srv_token_hash_line(const char *token, size_t n, char out[SRV_TOKEN_HASH_LINE]);

/* Reads the token file path into cfg->tokens at level (SRV_TOKEN_READ or SRV_TOKEN_WRITE).
 * 0, or -EINVAL / -ENOENT / -ENOMEM with err naming opt ("--token") and the file and line;
 * -E2BIG beyond SRV_TOKENS_MAX tokens in all. A file without any token is refused. */
int srv_token_load(const char *opt, const char *path, int level, srv_config_t *cfg, err_t *err);

/* What the presented token (n bytes) grants: SRV_TOKEN_WRITE, SRV_TOKEN_READ or SRV_TOKEN_NONE.
 * Its digest is compared with every configured digest, each comparison in constant time
 * (nettle's memeql_sec) and never stopping at the first match, so the time taken says nothing
 * about how much of a token was right. */
int srv_token_level(const srv_config_t *cfg, const char *token, size_t n);

/* Event-stream tickets (docs/api.md, Conventions): a browser's EventSource cannot send an
 * Authorization header, so with --read-token a client holding a read or write token first asks
 * for a ticket (POST /api/events/ticket) and opens GET /api/events?ticket=T. A ticket is
 * "EXPIRY.HMAC": EXPIRY the monotonic clock's milliseconds when it stops opening streams, HMAC
 * the hex HMAC-SHA256 of "ipsd-events:EXPIRY" under a key drawn from getrandom once per process.
 * So a ticket needs no table, grants only the event stream (read-only), ends with ipsd's process
 * and is useless to anyone after its EXPIRY. The request log never prints it (it prints no query
 * string); a proxy's log might, which is why it lives SRV_TICKET_TTL_MS only. */
#define SRV_TICKET_TTL_MS 60000
#define SRV_TICKET_MAX 96 /* 20 digits, '.', 64 hex digits, NUL, rounded up */

/* A ticket valid until now_ms + ttl_ms into out. 0, or -EIO with err when no random key could
 * be drawn (then no ticket is ever valid). */
int srv_token_ticket(long long now_ms, long long ttl_ms, char out[SRV_TICKET_MAX], err_t *err);

/* 1 when ticket is one of this process's, unaltered and not expired at now_ms; else 0 (the MAC is
 * compared in constant time). */
int srv_token_ticket_check(const char *ticket, long long now_ms);

#endif
