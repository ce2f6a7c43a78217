/* api_calib_cache.h: the encoded JSON of pixels' current calibrations, kept between requests so
 * the lab's most frequent read (GET /api/sensors/{id}/pixels/{col}/{row}/calibration) costs a
 * lookup and a copy instead of a query, a BLOB decode and a 17-digit JSON encoding. An entry is
 * valid while storage's calibration generation (storage_calib_generation) has not moved since
 * the entry's read began; every stored or promoted calibration moves it, so a write empties the
 * cache's view at once (calibration writes are rare against reads). Bounded in entries and bytes. */
#ifndef IPSD_API_API_CALIB_CACHE_H
#define IPSD_API_API_CALIB_CACHE_H

#include <stddef.h>
#include <stdint.h>

typedef struct api_calib_cache api_calib_cache_t;

/* A cache of at most slots entries (rounded up to a power of two) and max_bytes of text in all. */
api_calib_cache_t *api_calib_cache_new(size_t slots, size_t max_bytes);
void api_calib_cache_free(api_calib_cache_t *c);

/* The pixel's text (*len bytes, NUL-terminated) when an entry of generation gen is held, else
 * NULL (a miss). The text is the entry's own, shared and counted, not a copy: the caller gives
 * it back with api_calib_cache_release (it stays valid until then, even if the entry is replaced
 * or the cache freed), so a hit allocates nothing (a reply cached here takes no malloc arena's
 * lock: the copy of ~2.4 kB it took before was past glibc's per-thread cache, and an arena
 * shared with a preempted fit worker made the read wait for it). */
char *api_calib_cache_get(api_calib_cache_t *c, int64_t sensor, int64_t col, int64_t row,
                          uint64_t gen, size_t *len);

/* Gives back a text of api_calib_cache_get (thread-safe; a free callback of a libmicrohttpd
 * response: MHD_ContentReaderFreeCallback). */
void api_calib_cache_release(void *text);

/* Keeps a copy of text (len bytes), read at generation gen (the counter read BEFORE the read);
 * replaces what the slot held; skipped when the text would pass the byte bound. */
void api_calib_cache_put(api_calib_cache_t *c, int64_t sensor, int64_t col, int64_t row,
                         uint64_t gen, const char *text, size_t len);

/* Hits and misses since the start (for /api/health). */
void api_calib_cache_stats(api_calib_cache_t *c, uint64_t *hits, uint64_t *misses,
                           size_t *entries, size_t *bytes);

#endif
