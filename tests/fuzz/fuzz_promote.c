/* fuzz_promote.c: POST /api/fits/1/promote with any body: the promote request (api_promote.c: by, reason). */
#include "fuzz_api.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_request("POST", "/api/fits/1/promote", (const char *)data, size);
    return 0;
}
