# Tests of instrument/ (scenes, the simulated camera and stage, the scan procedure, the libcamera
# backend) and the end-to-end `ips simulate` -> `ips fit` test.
ipsd_add_test(test_scene ipsinstr)
ipsd_add_test(test_stage ipsinstr)
ipsd_add_test(test_cam_sim ipsinstr)
ipsd_add_test(test_scan ipsinstr)
set_tests_properties(test_scan PROPERTIES TIMEOUT 200) # busy, ASan: 47 s (optimised 6 s); 4x
ipsd_add_test(test_cam_libcamera ipsinstr)

if(TARGET ips)
    add_test(NAME test_simulate
             COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_simulate.sh $<TARGET_FILE:ips>
             WORKING_DIRECTORY ${IPSD_TEST_DATA})
    # busy 2-core machine, ASan build: 273 s (optimised: 122 s); 4x
    set_tests_properties(test_simulate PROPERTIES TIMEOUT 1100)
endif()
