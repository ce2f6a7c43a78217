/* fuzz_scan_create.c: POST /api/scans with any body: the scan request validator (api_scans.c: fields, optics by eq. 1, raster, geometry against the seeded sensor). */
#include "fuzz_api.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_request("POST", "/api/scans", (const char *)data, size);
    return 0;
}
