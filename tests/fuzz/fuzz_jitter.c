/* fuzz_jitter.c: POST /api/jitter with any body: the jitter-photometry request (api_jitter.c: the
 * maps, psf, position, jitter rms or series, measured fluxes) and fit/jitter.h behind it. */
#include "fuzz_api.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_request("POST", "/api/jitter", (const char *)data, size);
    return 0;
}
