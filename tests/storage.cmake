# Tests of storage/ (libipsstore): real SQLite files in a temporary directory.
if(TARGET ipsstore)
    find_package(Threads REQUIRED)
    ipsd_add_test(test_storage ipsstore Threads::Threads)
    # white-box: it reads storage/storage_int.h (the migrations) to build an old schema by hand
    target_include_directories(test_storage PRIVATE ${PROJECT_SOURCE_DIR}/storage)
endif()
