/* fuzz_sensor_create.c: POST /api/sensors with any body: the sensor validator (api_sensors.c). */
#include "fuzz_api.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_request("POST", "/api/sensors", (const char *)data, size);
    return 0;
}
