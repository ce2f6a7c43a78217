/* srv_token.c: bearer tokens stored as SHA-256 digests (see srv_token.h). SHA-256 and the
 * constant-time comparison are nettle's; the file format is ours (one token or "sha256:HEX" per
 * line). Plain tokens are wiped from memory (explicit_bzero) once hashed. */
#include "server/srv_token.h"

#include <errno.h>
#include <nettle/hmac.h>
#include <nettle/memops.h>
#include <nettle/sha2.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>

#define TOKEN_FILE_MAX 65536 /* a token file larger than this is refused */

void srv_token_digest(const void *data, size_t n, unsigned char out[SRV_TOKEN_DIGEST])
{
    struct sha256_ctx ctx;
    sha256_init(&ctx);
    sha256_update(&ctx, n, data);
    sha256_digest(&ctx, SHA256_DIGEST_SIZE, out);
    explicit_bzero(&ctx, sizeof ctx);
}

void srv_token_hash_line(const char *token, size_t n, char out[SRV_TOKEN_HASH_LINE])
{
    unsigned char d[SRV_TOKEN_DIGEST];
    srv_token_digest(token, n, d);
    int k = snprintf(out, SRV_TOKEN_HASH_LINE, "sha256:");
    for (int i = 0; i < SRV_TOKEN_DIGEST; i++)
        k += snprintf(out + k, (size_t)(SRV_TOKEN_HASH_LINE - k), "%02x", d[i]);
}

static int hex_value(char c)
{
    return c >= '0' && c <= '9'   ? c - '0'
           : c >= 'a' && c <= 'f' ? c - 'a' + 10
           : c >= 'A' && c <= 'F' ? c - 'A' + 10
                                  : -1;
}

/* One trimmed, non-empty line [s, s+n) into a digest: "sha256:HEX" or a plain token. */
static int parse_line(const char *opt, const char *path, int lineno, const char *s, size_t n,
                      unsigned char d[SRV_TOKEN_DIGEST], err_t *err)
{
    for (size_t i = 0; i < n; i++)
        if ((unsigned char)s[i] < 0x21 || (unsigned char)s[i] > 0x7e)
            return err_set(err, -EINVAL,
                           "%s: %s line %d holds whitespace or non-ASCII inside the token", opt,
                           path, lineno);
    if (n > 7 && strncmp(s, "sha256:", 7) == 0) {
        if (n != 7 + 2 * SRV_TOKEN_DIGEST)
            return err_set(err, -EINVAL, "%s: %s line %d: sha256: needs 64 hex digits", opt, path,
                           lineno);
        for (int i = 0; i < SRV_TOKEN_DIGEST; i++) {
            int hi = hex_value(s[7 + 2 * i]), lo = hex_value(s[8 + 2 * i]);
            if (hi < 0 || lo < 0)
                return err_set(err, -EINVAL, "%s: %s line %d: sha256: needs 64 hex digits", opt,
                               path, lineno);
            d[i] = (unsigned char)(hi << 4 | lo);
        }
        return 0;
    }
    srv_token_digest(s, n, d);
    return 0;
}

/* The lines of buf (NUL-terminated, len bytes) into cfg->tokens. */
static int parse_file(const char *opt, const char *path, char *buf, int level, srv_config_t *cfg,
                      err_t *err)
{
    int lineno = 0, found = 0;
    for (char *line = buf; line && *line;) {
        char *next = strchr(line, '\n');
        if (next) *next++ = 0;
        lineno++;
        char *s = line, *e = line + strlen(line);
        while (*s && strchr(" \t\r", *s))
            s++;
        while (e > s && strchr(" \t\r", e[-1]))
            e--;
        line = next;
        if (s == e || *s == '#') continue;
        if (cfg->n_tokens >= SRV_TOKENS_MAX)
            return err_set(err, -E2BIG, "%s: more than %d tokens in all", opt, SRV_TOKENS_MAX);
        srv_token_t *t = &cfg->tokens[cfg->n_tokens];
        int ret = parse_line(opt, path, lineno, s, (size_t)(e - s), t->sha256, err);
        if (ret) return ret;
        t->level = level;
        cfg->n_tokens++;
        found++;
    }
    return found ? 0 : err_set(err, -EINVAL, "%s: %s is empty (no token in it)", opt, path);
}

int srv_token_load(const char *opt, const char *path, int level, srv_config_t *cfg, err_t *err)
{
    FILE *f = fopen(path, "r");
    if (!f) return err_set(err, -errno, "%s: cannot read %s: %s", opt, path, strerror(errno));
    static const size_t cap = TOKEN_FILE_MAX + 1;
    char buf[TOKEN_FILE_MAX + 1];
    size_t n = fread(buf, 1, cap - 1, f);
    int more = fgetc(f) != EOF;
    fclose(f);
    int ret;
    if (more) {
        ret = err_set(err, -EINVAL, "%s: %s is longer than %d bytes", opt, path, TOKEN_FILE_MAX);
    } else if (memchr(buf, 0, n)) {
        ret = err_set(err, -EINVAL, "%s: %s holds a NUL byte", opt, path);
    } else {
        buf[n] = 0;
        ret = parse_file(opt, path, buf, level, cfg, err);
    }
    explicit_bzero(buf, n); /* the plain tokens: only their digests are kept */
    return ret;
}

int srv_token_level(const srv_config_t *cfg, const char *token, size_t n)
{
    unsigned char d[SRV_TOKEN_DIGEST];
    srv_token_digest(token, n, d);
    int level = SRV_TOKEN_NONE;
    for (int i = 0; i < cfg->n_tokens; i++) {
        int eq = memeql_sec(d, cfg->tokens[i].sha256, SRV_TOKEN_DIGEST);
        int l = cfg->tokens[i].level;
        level = eq && l > level ? l : level; /* no early exit: every digest is compared */
    }
    explicit_bzero(d, sizeof d);
    return level;
}

/* ---- event-stream tickets ---- */

static unsigned char ticket_key[32]; /* drawn once per process (ticket_key_init) */
static int ticket_key_ok;
static pthread_once_t ticket_once = PTHREAD_ONCE_INIT;

static void ticket_key_init(void)
{
    ticket_key_ok = getrandom(ticket_key, sizeof ticket_key, 0) == (ssize_t)sizeof ticket_key;
}

/* The hex HMAC-SHA256 of "ipsd-events:EXPIRY" (expiry: its decimal text) into hex. */
static void ticket_mac(const char *expiry, char hex[2 * SHA256_DIGEST_SIZE + 1])
{
    struct hmac_sha256_ctx ctx;
    unsigned char d[SHA256_DIGEST_SIZE];
    static const char tag[] = "ipsd-events:";
    hmac_sha256_set_key(&ctx, sizeof ticket_key, ticket_key);
    hmac_sha256_update(&ctx, sizeof tag - 1, (const uint8_t *)tag);
    hmac_sha256_update(&ctx, strlen(expiry), (const uint8_t *)expiry);
    hmac_sha256_digest(&ctx, sizeof d, d);
    explicit_bzero(&ctx, sizeof ctx);
    for (int i = 0; i < SHA256_DIGEST_SIZE; i++)
        snprintf(hex + 2 * i, 3, "%02x", d[i]);
}

int srv_token_ticket(long long now_ms, long long ttl_ms, char out[SRV_TICKET_MAX], err_t *err)
{
    pthread_once(&ticket_once, ticket_key_init);
    out[0] = 0;
    if (!ticket_key_ok) return err_set(err, -EIO, "no random key for event tickets (getrandom)");
    char expiry[24], mac[2 * SHA256_DIGEST_SIZE + 1];
    snprintf(expiry, sizeof expiry, "%lld", now_ms + ttl_ms);
    ticket_mac(expiry, mac);
    snprintf(out, SRV_TICKET_MAX, "%s.%s", expiry, mac);
    return 0;
}

int srv_token_ticket_check(const char *ticket, long long now_ms)
{
    pthread_once(&ticket_once, ticket_key_init);
    if (!ticket_key_ok || !ticket) return 0;
    const char *dot = strchr(ticket, '.');
    size_t n = dot ? (size_t)(dot - ticket) : 0;
    if (n == 0 || n > 19 || strlen(dot + 1) != 2 * SHA256_DIGEST_SIZE) return 0;
    char expiry[24], mac[2 * SHA256_DIGEST_SIZE + 1];
    for (size_t i = 0; i < n; i++)
        if (ticket[i] < '0' || ticket[i] > '9') return 0;
    memcpy(expiry, ticket, n);
    expiry[n] = 0;
    ticket_mac(expiry, mac);
    int same = memeql_sec(mac, dot + 1, 2 * SHA256_DIGEST_SIZE);
    return same && strtoll(expiry, NULL, 10) > now_ms;
}
