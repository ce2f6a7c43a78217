# FITS export and jitter photometry through a real ipsd and the ips tool: test_server_export.py,
# which reads the files back with astropy (Debian's python3-astropy; exit 77: skipped without it).
find_package(Python3 COMPONENTS Interpreter)
if(TARGET ipsd AND TARGET ips AND Python3_Interpreter_FOUND)
    add_test(NAME test_server_export
             COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/test_server_export.py
                     $<TARGET_FILE:ipsd> $<TARGET_FILE:ips>
             WORKING_DIRECTORY ${IPSD_TEST_DATA})
    # a small scan and two small fits: ~10 s optimised on a quiet machine; 4x for busy, ASan
    set_tests_properties(test_server_export PROPERTIES TIMEOUT 240 SKIP_RETURN_CODE 77)
endif()
