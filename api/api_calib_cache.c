/* api_calib_cache.c: the current-calibration reply cache (api_calib_cache.h). Direct-mapped:
 * a pixel hashes to one slot, a newer pixel replaces an older one there; one mutex, held only
 * for a lookup and a reference count's increment, so the HTTP threads do not queue behind it. */
#include "api_calib_cache.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

/* A text shared by its slot and the replies being sent: freed by its last holder. */
typedef struct shared {
    atomic_size_t refs;
    char text[]; /* NUL-terminated */
} shared_t;

typedef struct slot {
    int64_t sensor, col, row;
    uint64_t gen;
    char *text; /* NULL: empty; else the text of a shared_t */
    size_t len;
} slot_t;

static shared_t *shared_of(void *text)
{
    return (shared_t *)((char *)text - offsetof(shared_t, text));
}

void api_calib_cache_release(void *text)
{
    if (text && atomic_fetch_sub(&shared_of(text)->refs, 1) == 1) free(shared_of(text));
}

struct api_calib_cache {
    pthread_mutex_t mu;
    slot_t *slot;
    size_t mask;             /* slots - 1 (a power of two) */
    size_t max_bytes, bytes; /* bound and current total of the texts */
    size_t entries;
    uint64_t hits, misses;
};

api_calib_cache_t *api_calib_cache_new(size_t slots, size_t max_bytes)
{
    size_t n = 1;
    while (n < slots && n < ((size_t)1 << 20))
        n <<= 1;
    api_calib_cache_t *c = calloc(1, sizeof *c);
    if (!c || !(c->slot = calloc(n, sizeof *c->slot))) {
        free(c);
        return NULL;
    }
    pthread_mutex_init(&c->mu, NULL);
    c->mask = n - 1;
    c->max_bytes = max_bytes;
    return c;
}

void api_calib_cache_free(api_calib_cache_t *c)
{
    if (!c) return;
    for (size_t i = 0; i <= c->mask; i++)
        api_calib_cache_release(c->slot[i].text);
    pthread_mutex_destroy(&c->mu);
    free(c->slot);
    free(c);
}

/* The slot of a pixel: a 64-bit mix of the three ids (splitmix64's finaliser). */
static slot_t *slot_of(api_calib_cache_t *c, int64_t sensor, int64_t col, int64_t row)
{
    uint64_t h = (uint64_t)sensor * 0x9e3779b97f4a7c15u ^ (uint64_t)col * 0xc2b2ae3d27d4eb4fu ^
                 (uint64_t)row * 0x165667b19e3779f9u;
    h ^= h >> 30;
    h *= 0xbf58476d1ce4e5b9u;
    h ^= h >> 27;
    h *= 0x94d049bb133111ebu;
    h ^= h >> 31;
    return &c->slot[h & c->mask];
}

static int holds(const slot_t *s, int64_t sensor, int64_t col, int64_t row)
{
    return s->text && s->sensor == sensor && s->col == col && s->row == row;
}

char *api_calib_cache_get(api_calib_cache_t *c, int64_t sensor, int64_t col, int64_t row,
                          uint64_t gen, size_t *len)
{
    if (!c) return NULL;
    char *out = NULL;
    pthread_mutex_lock(&c->mu);
    slot_t *s = slot_of(c, sensor, col, row);
    if (holds(s, sensor, col, row) && s->gen == gen) {
        atomic_fetch_add(&shared_of(s->text)->refs, 1);
        out = s->text;
        *len = s->len;
    }
    if (out)
        c->hits++;
    else
        c->misses++;
    pthread_mutex_unlock(&c->mu);
    return out;
}

void api_calib_cache_put(api_calib_cache_t *c, int64_t sensor, int64_t col, int64_t row,
                         uint64_t gen, const char *text, size_t len)
{
    if (!c) return;
    shared_t *sh = malloc(sizeof *sh + len + 1);
    if (!sh) return;
    atomic_init(&sh->refs, 1); /* the slot's */
    char *copy = sh->text;
    memcpy(copy, text, len);
    copy[len] = 0;
    pthread_mutex_lock(&c->mu);
    slot_t *s = slot_of(c, sensor, col, row);
    size_t freed = s->text ? s->len : 0;
    if (s->text && holds(s, sensor, col, row) && s->gen > gen) {
        /* a newer reader filled it already: keep the newer text */
        free(sh);
    } else if (c->bytes - freed + len > c->max_bytes) {
        free(sh); /* over the bound: serve uncached rather than grow */
    } else {
        if (s->text) {
            api_calib_cache_release(s->text); /* freed when no reply sends it any more */
            c->bytes -= freed;
            c->entries--;
        }
        *s = (slot_t){sensor, col, row, gen, copy, len};
        c->bytes += len;
        c->entries++;
    }
    pthread_mutex_unlock(&c->mu);
}

void api_calib_cache_stats(api_calib_cache_t *c, uint64_t *hits, uint64_t *misses, size_t *entries,
                           size_t *bytes)
{
    *hits = *misses = 0;
    *entries = *bytes = 0;
    if (!c) return;
    pthread_mutex_lock(&c->mu);
    *hits = c->hits;
    *misses = c->misses;
    *entries = c->entries;
    *bytes = c->bytes;
    pthread_mutex_unlock(&c->mu);
}
