/* fuzz_scan_fit.c: POST /api/scans/1/fits with any body: the fit request of a scan's pixel (api_fits.c: dcol/drow, the fit options, promote; the seeded scan is not done, so a valid request ends in 409). */
#include "fuzz_api.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_request("POST", "/api/scans/1/fits", (const char *)data, size);
    return 0;
}
