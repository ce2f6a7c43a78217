# Tests of server/ (libipssrv) and api/ (libipsapi, ipsd): unit tests in C, and HTTP tests that
# start the real daemon on a free loopback port and talk to it with curl (bash scripts; python3,
# curl and the sqlite3 shell from Debian).
if(TARGET ipsapi)
    ipsd_add_test(test_server ipssrv)
    ipsd_add_test(test_api ipsapi)
    # white-box: it calls api/api_int.h's request-independent helpers directly
    target_include_directories(test_api PRIVATE ${PROJECT_SOURCE_DIR}/api)
endif()
# test_server_flow compares the stored maps with `ips fit` (cli/), so it needs ips too
if(TARGET ipsapi AND TARGET ips)
    foreach(t flow restart input)
        add_test(NAME test_server_${t}
                 COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_server_${t}.sh $<TARGET_FILE:ipsd>
                         $<TARGET_FILE:ips>
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        set_tests_properties(test_server_${t} PROPERTIES TIMEOUT 120)
    endforeach()
endif()
