# FITS export and import: test_server_export.py (calibrations as FITS and jitter photometry
# through a real ipsd and ips, read back with astropy) and test_import_fits.py (ips import-fits;
# Debian's python3-astropy; exit 77: skipped without it).
find_package(Python3 COMPONENTS Interpreter)
if(TARGET ipsd AND TARGET ips AND Python3_Interpreter_FOUND)
    add_test(NAME test_server_export
             COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/test_server_export.py
                     $<TARGET_FILE:ipsd> $<TARGET_FILE:ips>
             WORKING_DIRECTORY ${IPSD_TEST_DATA})
    # a small scan and two small fits: ~10 s optimised on a quiet machine; 4x for busy, ASan
    set_tests_properties(test_server_export PROPERTIES TIMEOUT 240 SKIP_RETURN_CODE 77)
endif()

# ips import-fits (and POST /api/fits's scan_fits): a lab's FITS scan cube (written by astropy, the independent writer) as a scan
# file, equal to the simulator's, and its bad inputs (test_import_fits.py; 77: no astropy).
# With ipsd, POST /api/fits's scan_fits too; its answers are recorded for tests/apilint.cmake.
if(TARGET ips AND TARGET ipsd AND Python3_Interpreter_FOUND)
    add_test(NAME test_import_fits
             COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/test_import_fits.py
                     $<TARGET_FILE:ips> $<TARGET_FILE:ipsd>
             WORKING_DIRECTORY ${CMAKE_CURRENT_SOURCE_DIR})
    # 6 simulations and 6 fits of small scans: ~20 s of CPU under ASan; 12-50 s optimised and
    # 250 s under ASan measured on a machine at load average 29 on 2 cores
    set_tests_properties(test_import_fits PROPERTIES TIMEOUT 600 SKIP_RETURN_CODE 77
        ENVIRONMENT "IPSD_API_RECORD_DIR=${IPSD_API_RECORD_DIR}" FIXTURES_SETUP api_records)
endif()

# fitsmap_write's files read back by a minimal reader in the test, one written after another in
# reused heap memory (~0.1 s)
ipsd_add_test(test_fitsmap ipsexport)
