/* srv_token.h: ipsd's bearer tokens: the token files of --token (write) and --read-token (read),
 * kept only as SHA-256 digests, and the check of a presented token. A token file holds one token
 * per line (blank lines and lines starting with '#' are skipped, surrounding whitespace trimmed):
 * either the token itself, hashed when read and the plain text wiped, or "sha256:" and the 64
 * hex digits of its digest (so a lab can keep only hashes on disk; `ipsd --hash-token` prints
 * that line). SHA-256 is nettle's (the library GnuTLS, and so libmicrohttpd, stands on).
 * Thread-safe: functions only read what they are given. */
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

#endif
