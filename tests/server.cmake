# Tests of server/ (libipssrv) and api/ (libipsapi, ipsd): unit tests in C, and HTTP tests that
# start the real daemon on a free loopback port and talk to it with one long-lived HTTP client
# (Python 3 scripts, standard library only: http.client, sqlite3 as the independent reader of the
# database, subprocess; tests/ipsd_http.py). They stop jobs at known points with ipsd's failpoints
# (docs/server.md, "Test hooks") instead of racing the workers.
if(TARGET ipsapi)
    ipsd_add_test(test_server ipssrv)
    ipsd_add_test(test_api ipsapi)
    # white-box: it calls api/api_int.h's request-independent functions directly
    target_include_directories(test_api PRIVATE ${PROJECT_SOURCE_DIR}/api)
endif()
# test_server_flow compares the stored maps with `ips fit` (cli/), so it needs ips too
find_package(Python3 COMPONENTS Interpreter)
if(TARGET ipsapi AND TARGET ips AND Python3_Interpreter_FOUND)
    # TIMEOUT (tests/CMakeLists.txt): seconds on a busy 2-core machine, ASan build: flow 31,
    # restart 93, input 20, promote ~25 (optimised: 11, 26, 9, 6.5; hostile 3, flood 8; region: 4
    # fits of a 225-point upload; storfault ~40 s optimised: three daemons, four 961-point scans each;
    # camfault ~10 s; security 4 / ASan 11, backup 12-21 / ASan 71; crash: 8 starts
    # and 4 small fits, 10 s optimised; fitstop 21 starts, 6 small fits, 77 s optimised on a busy machine). One test per line below,
    # so branches that add tests merge without conflicts.
    foreach(t flow:130 restart:380 input:80 promote:120 region:120 hostile:60 flood:200
            calib_cache:90
            log:60
            scanend:120
            security:60
            static:60
            backup:240
            crash:150
            fitstop:300
            sched:60
            storfault:240
            camfault:120
            allpixels:200
            scanfile:900
            stage:300
            ptc:300
            zaber:300
            points:120
            adaptive:240
            )
        string(REPLACE ":" ";" t ${t})
        list(GET t 0 name)
        list(GET t 1 timeout)
        add_test(NAME test_server_${name}
                 COMMAND ${Python3_EXECUTABLE} -B
                         ${CMAKE_CURRENT_SOURCE_DIR}/test_server_${name}.py $<TARGET_FILE:ipsd>
                         $<TARGET_FILE:ips>
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        # every answer is recorded for tests/apilint.cmake's check against api/openapi.json
        set_tests_properties(test_server_${name} PROPERTIES TIMEOUT ${timeout}
            ENVIRONMENT "IPSD_API_RECORD_DIR=${IPSD_API_RECORD_DIR}"
            FIXTURES_SETUP api_records)
    endforeach()
    # the HTTP tests whose ipsd does not depend on SQLite again, each ipsd on a fresh schema of the
    # PostgreSQL server of tests/pg.cmake and the database read back with psql
    # (tests/ipsd_http.py); the same timeouts as their SQLite runs. storfault runs there the
    # cases that are not SQLite's own, and one of its own: ipsd's role losing its privileges
    if(TEST pg_server_start)
        foreach(t flow:130 restart:380 input:80 promote:120 region:120 calib_cache:90 crash:150
                fitstop:300 allpixels:200 points:120 scanend:120 ptc:300 security:60
                hostile:60 flood:200 log:60 static:60 sched:60 stage:300 zaber:300 scanfile:900
                export:240 camfault:120 adaptive:240 storfault:240)
            string(REPLACE ":" ";" t ${t})
            list(GET t 0 name)
            list(GET t 1 timeout)
            add_test(NAME test_server_${name}_pg
                     COMMAND ${Python3_EXECUTABLE} -B
                             ${CMAKE_CURRENT_SOURCE_DIR}/test_server_${name}.py $<TARGET_FILE:ipsd>
                             $<TARGET_FILE:ips>
                     WORKING_DIRECTORY ${IPSD_TEST_DATA})
            set_tests_properties(test_server_${name}_pg PROPERTIES TIMEOUT ${timeout}
                FIXTURES_REQUIRED pg FIXTURES_SETUP api_records SKIP_RETURN_CODE 77
                ENVIRONMENT "IPSD_API_RECORD_DIR=${IPSD_API_RECORD_DIR};IPSD_TEST_PG_URI_FILE=${IPSD_PG_DIR}/uri;PGPASSFILE=${IPSD_PG_DIR}/pgpass")
        endforeach()
    endif()
    # several ipsd on one PostgreSQL database: four benches and a fit worker, benches killed
    # mid-scan and mid-fit, the database server restarted, a bench name's lock taken over and
    # back (about 40 s optimised)
    if(TEST pg_server_start)
        # its own server (it restarts it, which the other tests of the fixture must not see)
        add_test(NAME test_server_shared
                 COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/test_server_shared.py
                         $<TARGET_FILE:ipsd> $<TARGET_FILE:ips>
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        set_tests_properties(test_server_shared PROPERTIES TIMEOUT 400 SKIP_RETURN_CODE 77
            ENVIRONMENT "IPSD_API_RECORD_DIR=${IPSD_API_RECORD_DIR}"
            FIXTURES_SETUP api_records)
    endif()
    # a bench's SQLite database copied into the PostgreSQL one (ipsd --db-copy), twice
    if(TEST pg_server_start)
        add_test(NAME test_server_dbcopy
                 COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/test_server_dbcopy.py
                         $<TARGET_FILE:ipsd> $<TARGET_FILE:ips> ${IPSD_PG_DIR}/uri
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        set_tests_properties(test_server_dbcopy PROPERTIES TIMEOUT 300 FIXTURES_REQUIRED pg
            SKIP_RETURN_CODE 77
            ENVIRONMENT "IPSD_API_RECORD_DIR=${IPSD_API_RECORD_DIR};PGPASSFILE=${IPSD_PG_DIR}/pgpass"
            FIXTURES_SETUP api_records)
    endif()
    # a PostgreSQL database backed up with pg_dump while a scan is held, restored with
    # pg_restore into a new database and resumed there, by docs/operations.md's commands; ipsd's
    # own backups refuse it and say so
    if(TEST pg_server_start)
        add_test(NAME test_server_pgbackup
                 COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/test_server_pgbackup.py
                         $<TARGET_FILE:ipsd> $<TARGET_FILE:ips> ${IPSD_PG_DIR}/uri
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        set_tests_properties(test_server_pgbackup PROPERTIES TIMEOUT 240 FIXTURES_REQUIRED pg
            SKIP_RETURN_CODE 77
            ENVIRONMENT "IPSD_API_RECORD_DIR=${IPSD_API_RECORD_DIR};PGPASSFILE=${IPSD_PG_DIR}/pgpass"
            FIXTURES_SETUP api_records)
    endif()
    # the scans through Aravis's GigE Vision emulator (tests/aravis.cmake) on PostgreSQL too: a
    # camera path's points, frame times and provenance stored by the other driver
    if(TEST pg_server_start AND TEST test_server_aravis)
        add_test(NAME test_server_aravis_pg
                 COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/test_server_aravis.py
                         $<TARGET_FILE:ipsd> $<TARGET_FILE:ips> $<TARGET_FILE:arv_emulator>
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        add_test(NAME test_server_aravis_scene_pg
                 COMMAND ${Python3_EXECUTABLE} -B
                         ${CMAKE_CURRENT_SOURCE_DIR}/test_server_aravis_scene.py
                         $<TARGET_FILE:ipsd> $<TARGET_FILE:ips> $<TARGET_FILE:arv_emulator>
                         ${CMAKE_CURRENT_SOURCE_DIR}/gcs_emulator.py
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        set_tests_properties(test_server_aravis_pg test_server_aravis_scene_pg PROPERTIES
            TIMEOUT 300 RESOURCE_LOCK gige_emulator FIXTURES_REQUIRED pg SKIP_RETURN_CODE 77
            FIXTURES_SETUP api_records
            ENVIRONMENT "IPSD_API_RECORD_DIR=${IPSD_API_RECORD_DIR};IPSD_TEST_PG_URI_FILE=${IPSD_PG_DIR}/uri;PGPASSFILE=${IPSD_PG_DIR}/pgpass")
    endif()
    # SIGTERM under a flood of connections, with epoll removals slowed by an LD_PRELOAD shim
    # (test_server_quiesce.py: 30 starts and stops, ~10 s optimised)
    add_library(shim_epoll_slowdel MODULE shim_epoll_slowdel.c)
    target_link_libraries(shim_epoll_slowdel PRIVATE ${CMAKE_DL_LIBS})
    add_test(NAME test_server_quiesce
             COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/test_server_quiesce.py
                     $<TARGET_FILE:ipsd> $<TARGET_FILE:ips> $<TARGET_FILE:shim_epoll_slowdel>
             WORKING_DIRECTORY ${IPSD_TEST_DATA})
    set_tests_properties(test_server_quiesce PROPERTIES TIMEOUT 120
        ENVIRONMENT "IPSD_API_RECORD_DIR=${IPSD_API_RECORD_DIR}"
        FIXTURES_SETUP api_records)
    if(TEST pg_server_start)
        add_test(NAME test_server_quiesce_pg
                 COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/test_server_quiesce.py
                         $<TARGET_FILE:ipsd> $<TARGET_FILE:ips> $<TARGET_FILE:shim_epoll_slowdel>
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        set_tests_properties(test_server_quiesce_pg PROPERTIES TIMEOUT 120 SKIP_RETURN_CODE 77
            FIXTURES_REQUIRED pg
            ENVIRONMENT "IPSD_TEST_PG_URI_FILE=${IPSD_PG_DIR}/uri;PGPASSFILE=${IPSD_PG_DIR}/pgpass")
    endif()
elseif(TARGET ipsapi)
    message(STATUS "server HTTP tests: python3 or the ips target missing, not registered")
endif()
