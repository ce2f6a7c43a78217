/* fuzz_router.c: the URL router: "METHOD URL" (the first space separates them; up to the first
 * NUL) through api_unescape_keep_nul, api_route_find, api_route_allow and the 404 / 405 error
 * bodies that quote the path (fuzz_route). */
#include <stdlib.h>
#include <string.h>

#include "fuzz_api.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1);
    if (!text) return 0;
    memcpy(text, data, size);
    text[size] = 0;
    char *url = strchr(text, ' ');
    if (url) {
        *url++ = 0;
        fuzz_route(text, url);
    }
    free(text);
    return 0;
}
