/* fuzz_query.c: a GET of any URL: the path through the unescape and the router to a handler, the
 * query string split and unescaped as libmicrohttpd does and read by the list endpoints' query
 * parsing (api_input.c: limit, offset, state, sensor, kind, format, n, r...). The input is the
 * URL as it would come on the wire, up to its first NUL. */
#include <stdlib.h>
#include <string.h>

#include "fuzz_api.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *url = malloc(size + 1);
    if (!url) return 0;
    memcpy(url, data, size);
    url[size] = 0;
    fuzz_request("GET", url, NULL, 0);
    free(url);
    return 0;
}
