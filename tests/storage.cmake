# Tests of storage/ (libipsstore): real SQLite files in a temporary directory.
if(TARGET ipsstore)
    find_package(Threads REQUIRED)
    ipsd_add_test(test_storage ipsstore Threads::Threads)
    set_tests_properties(test_storage PROPERTIES TIMEOUT 80) # busy, ASan: 20 s (optimised 11 s)
    # white-box: it reads storage/storage_int.h (the migrations) to build an old schema by hand
    target_include_directories(test_storage PRIVATE ${PROJECT_SOURCE_DIR}/storage)
endif()
