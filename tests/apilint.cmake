# tests/apilint.cmake: the OpenAPI document against the ecosystem's tools and the server
# (docs/api.md "Checking the document").
#   openapi_lint       Redocly's CLI, recommended rules: zero errors and zero warnings, on the file
#                      and on the document a real ipsd serves
#   openapi_examples   every example in the document validates against its schema (ajv)
#   openapi_answers    every answer the HTTP tests received (the api_records fixture: tests/
#                      server.cmake) has a documented status and validates against its schema
# The tools are pinned by tests/apilint/package-lock.json (`npm ci --prefix tests/apilint`, done
# by scripts/test.sh); without them the tests skip (exit 77).
find_program(IPSD_NODE node)
if(NOT IPSD_NODE OR NOT TARGET ipsd)
    message(STATUS "OpenAPI checks: node or the ipsd target missing, not registered")
    return()
endif()
set(IPSD_APILINT ${CMAKE_CURRENT_SOURCE_DIR}/apilint)
add_test(NAME openapi_lint
         COMMAND ${IPSD_NODE} ${IPSD_APILINT}/lint.mjs ${PROJECT_SOURCE_DIR}/api/openapi.json
                 $<TARGET_FILE:ipsd>)
add_test(NAME openapi_examples
         COMMAND ${IPSD_NODE} ${IPSD_APILINT}/validate.mjs ${PROJECT_SOURCE_DIR}/api/openapi.json
                 --examples)
# 20 of the document's operations are reached by the HTTP tests; fewer means a test stopped
# recording (or lost its coverage)
add_test(NAME openapi_answers
         COMMAND ${IPSD_NODE} ${IPSD_APILINT}/validate.mjs ${PROJECT_SOURCE_DIR}/api/openapi.json
                 ${IPSD_API_RECORD_DIR} --min-operations 20)
# lint: ~5 s (Redocly loads ~200 MB of modules); the others ~1 s
set_tests_properties(openapi_lint openapi_examples openapi_answers PROPERTIES
                     SKIP_RETURN_CODE 77 TIMEOUT 120)
set_tests_properties(openapi_answers PROPERTIES FIXTURES_REQUIRED api_records)
