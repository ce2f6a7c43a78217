# Tests of server/ (libipssrv) and api/ (libipsapi, ipsd): unit tests in C, and HTTP tests that
# start the real daemon on a free loopback port and talk to it with one long-lived HTTP client
# (Python 3 scripts, standard library only: http.client, sqlite3 as the independent reader of the
# database, subprocess; tests/ipsd_http.py). They stop jobs at known points with ipsd's failpoints
# (docs/server.md, "Test hooks") instead of racing the workers.
if(TARGET ipsapi)
    ipsd_add_test(test_server ipssrv)
    ipsd_add_test(test_api ipsapi)
    # white-box: it calls api/api_int.h's request-independent helpers directly
    target_include_directories(test_api PRIVATE ${PROJECT_SOURCE_DIR}/api)
endif()
# test_server_flow compares the stored maps with `ips fit` (cli/), so it needs ips too
find_package(Python3 COMPONENTS Interpreter)
if(TARGET ipsapi AND TARGET ips AND Python3_Interpreter_FOUND)
    foreach(t flow restart input)
        add_test(NAME test_server_${t}
                 COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/test_server_${t}.py
                         $<TARGET_FILE:ipsd> $<TARGET_FILE:ips>
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
    endforeach()
elseif(TARGET ipsapi)
    message(STATUS "server HTTP tests: python3 or the ips target missing, not registered")
endif()
