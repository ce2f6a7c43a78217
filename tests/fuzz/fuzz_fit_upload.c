/* fuzz_fit_upload.c: POST /api/fits with any body: the fit request of an uploaded scan file (api_fits.c: the options, the scan file through srv_upload_check and the scan-file reader, the calibration target). */
#include "fuzz_api.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_request("POST", "/api/fits", (const char *)data, size);
    return 0;
}
