# tests/web.cmake: the dashboard's test (docs/web.md).
#   web_dashboard  the real-browser end-to-end test: a real ipsd, Debian's chromium driven by
#                  playwright-core (tests/web/package-lock.json; `npm ci --prefix tests/web`).
#                  Registered when node and /usr/bin/chromium exist; it skips (exit 77) when
#                  tests/web/node_modules is missing.
find_program(IPSD_NODE node)
if(NOT IPSD_NODE)
    message(STATUS "web tests: node not found, not registered")
    return()
endif()

if(EXISTS /usr/bin/chromium AND TARGET ipsd)
    add_test(NAME web_dashboard
             COMMAND ${IPSD_NODE} ${CMAKE_CURRENT_SOURCE_DIR}/web/dashboard.test.mjs
                     $<TARGET_FILE:ipsd> ${PROJECT_SOURCE_DIR}/web
                     ${CMAKE_BINARY_DIR}/web-screenshots)
    # busy 2-core machine: 60-140 s (140 s with 8 builds running: two more fits and the pixel
    # view), its own watchdog at 420 s; ~3.5x margin
    # the JSON answers the page and the test got are recorded like the HTTP tests' (tests/
    # server.cmake) for openapi_answers (tests/apilint.cmake), which therefore runs after it
    set_tests_properties(web_dashboard PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 480
        ENVIRONMENT "IPSD_API_RECORD_DIR=${IPSD_API_RECORD_DIR}" FIXTURES_SETUP api_records)
else()
    message(STATUS "web tests: /usr/bin/chromium or the ipsd target missing, web_dashboard not "
                   "registered")
endif()
