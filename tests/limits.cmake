# The scan's defaults and limits (instrument/scan_limits.h) agree across a real ipsd's OpenAPI
# document, its POST /api/scans and `ips simulate` (python3's standard library only).
if(TARGET ipsapi AND TARGET ips)
    add_test(NAME test_scan_limits
             COMMAND python3 ${CMAKE_CURRENT_SOURCE_DIR}/test_scan_limits.py $<TARGET_FILE:ipsd>
                     $<TARGET_FILE:ips>
             WORKING_DIRECTORY ${IPSD_TEST_DATA})
    set_tests_properties(test_scan_limits PROPERTIES TIMEOUT 600)
endif()
