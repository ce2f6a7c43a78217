# Tests of storage/ (libipsstore): real SQLite files in a temporary directory, and the layering of
# its files (no call cycle, statements by table) read from the built archive with nm.
if(TARGET ipsstore)
    find_package(Threads REQUIRED)
    ipsd_add_test(test_storage ipsstore Threads::Threads)
    set_tests_properties(test_storage PROPERTIES TIMEOUT 80) # busy, ASan: 20 s (optimised 11 s)
    # white-box: it reads storage/storage_int.h (the migrations) to build an old schema by hand
    target_include_directories(test_storage PRIVATE ${PROJECT_SOURCE_DIR}/storage)
    # the same tests on PostgreSQL (the server of tests/pg.cmake), each database a schema
    if(TEST pg_server_start)
        add_test(NAME test_storage_pg
                 COMMAND test_storage --pg-uri-file ${IPSD_PG_DIR}/uri
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        set_tests_properties(test_storage_pg PROPERTIES FIXTURES_REQUIRED pg
                             SKIP_RETURN_CODE 77 TIMEOUT 120
                             ENVIRONMENT "PGPASSFILE=${IPSD_PG_DIR}/pgpass")
    endif()
    ipsd_add_test(test_storage_ptc ipsstore) # photon-transfer history (schema 4), jobs (5)
    target_include_directories(test_storage_ptc PRIVATE ${PROJECT_SOURCE_DIR}/storage)
    ipsd_add_test(test_storage_backup ipsstore) # SQLite (raw reads of the copy) comes with it
    add_test(NAME test_storage_layers
             COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_storage_layers.sh ${CMAKE_NM}
                     $<TARGET_FILE:ipsstore> ${PROJECT_SOURCE_DIR}/storage)
    set_tests_properties(test_storage_layers PROPERTIES TIMEOUT 60) # nm and a sort: about 1 s
endif()
