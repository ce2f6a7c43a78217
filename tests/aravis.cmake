# aravis.cmake: the tests of the Aravis camera backend (instrument/cam_aravis.c), built when its
# module is: against Aravis's own GigE Vision camera emulator on 127.0.0.1, run inside the test
# (test_cam_aravis) or as a process (arv_emulator, for the HTTP tests of ipsd --bench aravis:ID),
# so the tests link Aravis and ipsd does not. The emulator binds the GigE Vision control port 3956
# of 127.0.0.1: the tests that run one hold the lock "gige_emulator" and run one at a time, and
# across ctest runs (other build or work trees) each such test holds a lock file (gige_lock.h).
if(TARGET ipscam_aravis)
    pkg_check_modules(ARAVIS_TEST IMPORTED_TARGET aravis-0.8)
    ipsd_add_test(test_cam_aravis ipsinstr PkgConfig::ARAVIS_TEST)
    add_dependencies(test_cam_aravis ipscam_aravis)
    # a camera that goes away costs Aravis's control timeouts: ~20 s, most of it waiting (its
    # release in the background, which the test waits for, and a capture's unanswered trigger)
    set_tests_properties(test_cam_aravis PROPERTIES TIMEOUT 120 RESOURCE_LOCK gige_emulator)
    # the reset after a frame that did not come, its release held at a test hook: ~20 s, most of
    # it Aravis's timeouts against the camera gone (its release, then its close's)
    add_test(NAME test_cam_aravis_reset COMMAND test_cam_aravis --reset
             WORKING_DIRECTORY ${IPSD_TEST_DATA})
    set_tests_properties(test_cam_aravis_reset PROPERTIES TIMEOUT 120 RESOURCE_LOCK gige_emulator)

    add_executable(arv_emulator arv_emulator.c)
    target_link_libraries(arv_emulator PRIVATE ipsinstr PkgConfig::ARAVIS_TEST)
    find_package(Python3 COMPONENTS Interpreter)
    if(TARGET ipsd AND TARGET ips AND Python3_Interpreter_FOUND)
        add_dependencies(arv_emulator ipscam_aravis)
        add_test(NAME test_server_aravis
                 COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/test_server_aravis.py
                         $<TARGET_FILE:ipsd> $<TARGET_FILE:ips> $<TARGET_FILE:arv_emulator>
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        # ~14 s, some of it Aravis's timeouts on the camera gone; 10x
        set_tests_properties(test_server_aravis PROPERTIES TIMEOUT 150
            RESOURCE_LOCK gige_emulator
            ENVIRONMENT "IPSD_API_RECORD_DIR=${IPSD_API_RECORD_DIR}"
            FIXTURES_SETUP api_records)
        # a whole scan through the emulator drawing the simulated bench where the emulated PI
        # controller is, against the same scan on --bench sim
        add_test(NAME test_server_aravis_scene
                 COMMAND ${Python3_EXECUTABLE} -B
                         ${CMAKE_CURRENT_SOURCE_DIR}/test_server_aravis_scene.py
                         $<TARGET_FILE:ipsd> $<TARGET_FILE:ips> $<TARGET_FILE:arv_emulator>
                         ${CMAKE_CURRENT_SOURCE_DIR}/gcs_emulator.py
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        set_tests_properties(test_server_aravis_scene PROPERTIES TIMEOUT 300
            RESOURCE_LOCK gige_emulator
            ENVIRONMENT "IPSD_API_RECORD_DIR=${IPSD_API_RECORD_DIR}"
            FIXTURES_SETUP api_records)
    endif()
endif()
