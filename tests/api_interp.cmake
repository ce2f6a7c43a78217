# tests/api_interp.cmake: the interpolated-map routes of the API (GET /api/fits/{id}/interp,
# GET /api/calibrations/{id}/interp) over HTTP against a real ipsd: tests/test_api_interp.py,
# Python 3's standard library only.
find_program(IPSD_PYTHON3 python3)
if(TARGET ipsd AND IPSD_PYTHON3)
    add_test(NAME test_api_interp
             COMMAND ${IPSD_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/test_api_interp.py
                     $<TARGET_FILE:ipsd>)
    # 6 s on a quiet machine; with both cores busy 50-82 s optimised and 147-171 s under ASan
    # (the fit worker runs at nice +10, so other load starves it first): 4x the slowest
    set_tests_properties(test_api_interp PROPERTIES TIMEOUT 700)
endif()
