# Tests of storage/ (libipsstore): real SQLite files in a temporary directory.
if(TARGET ipsstore)
    find_package(Threads REQUIRED)
    ipsd_add_test(test_storage ipsstore Threads::Threads)
endif()
