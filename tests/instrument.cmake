# Tests of instrument/ (scenes, the simulated camera and stage, the scan procedure, the libcamera
# backend) and the end-to-end `ips simulate` -> `ips fit` test.
ipsd_add_test(test_scene ipsinstr)
ipsd_add_test(test_stage ipsinstr)
# the GCS 2.0 stage backend against the emulated PI controller tests/gcs_emulator.py (python3)
find_package(Python3 COMPONENTS Interpreter)
if(Python3_Interpreter_FOUND)
    ipsd_add_test(test_stage_gcs ipsinstr)
    target_compile_definitions(test_stage_gcs PRIVATE
        IPSD_GCS_EMULATOR="${CMAKE_CURRENT_SOURCE_DIR}/gcs_emulator.py"
        IPSD_PYTHON3="${Python3_EXECUTABLE}")
    set_tests_properties(test_stage_gcs PROPERTIES TIMEOUT 300) # 14 emulator starts: 41 s at load 20
    # the Zaber ASCII backend against the emulated devices tests/zaber_emulator.py
    ipsd_add_test(test_stage_zaber ipsinstr)
    target_compile_definitions(test_stage_zaber PRIVATE
        IPSD_ZABER_EMULATOR="${CMAKE_CURRENT_SOURCE_DIR}/zaber_emulator.py"
        IPSD_PYTHON3="${Python3_EXECUTABLE}")
    set_tests_properties(test_stage_zaber PROPERTIES TIMEOUT 300) # 12 emulator starts
endif()
ipsd_add_test(test_cam_sim ipsinstr)
ipsd_add_test(test_scan ipsinstr)
ipsd_add_test(test_scan_cover ipsinstr) # which pixels a raster covers
ipsd_add_test(test_fidelity ipsinstr) # the short form of the fidelity harness
set_tests_properties(test_fidelity PROPERTIES TIMEOUT 300) # busy, ASan: the kriged maps ~4x
ipsd_add_test(test_krige_prior ipsinstr) # the kriged map's prior from the sweep, against the truth
set_tests_properties(test_krige_prior PROPERTIES TIMEOUT 120) # 7 cases, ~1 s; busy, ASan ~4x
set_tests_properties(test_scan PROPERTIES TIMEOUT 200) # busy, ASan: 47 s (optimised 6 s); 4x

# the libcamera backend: a module loaded at run time; the test knows whether it was built and
# where (to check IPSD_CAM_MODULE_PATH)
ipsd_add_test(test_cam_libcamera ipsinstr)
if(TARGET ipscam_libcamera)
    add_dependencies(test_cam_libcamera ipscam_libcamera)
    target_compile_definitions(test_cam_libcamera PRIVATE IPSD_HAVE_LIBCAMERA
        IPSD_TEST_CAM_MODULE_DIR="$<TARGET_FILE_DIR:ipscam_libcamera>")
endif()

# ips and ipsd load libcamera and Aravis only when their backend is asked for: neither needs
# libcamera, Aravis or glib, nor libstdc++ (ldd lists what the loader maps at start; libc proves ldd read the file). Sanitized
# builds are let off libstdc++: the UBSan run-time brings it. A static ips (IPSD_STATIC_CLI) maps
# no library at all: ldd's "not a dynamic executable" passes for it.
if(IPSD_SANITIZE)
    set(ipsd_unwanted_libs "libcamera|libaravis|libglib")
else()
    set(ipsd_unwanted_libs "libcamera|libaravis|libglib|libstdc\\+\\+")
endif()
foreach(exe ips ipsd)
    if(TARGET ${exe})
        add_test(NAME test_${exe}_without_libcamera
                 COMMAND sh -c "l=$(ldd \"$1\" 2>&1); echo \"$l\" | grep -q 'libc\\.so\\|not a dynamic executable' && ! echo \"$l\" | grep -E \"$2\""
                         sh $<TARGET_FILE:${exe}> "${ipsd_unwanted_libs}")
    endif()
endforeach()

if(TARGET ips)
    add_test(NAME test_simulate
             COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_simulate.sh $<TARGET_FILE:ips>
             WORKING_DIRECTORY ${IPSD_TEST_DATA})
    # busy 2-core machine, ASan build: 273 s (optimised: 122 s); 4x
    set_tests_properties(test_simulate PROPERTIES TIMEOUT 1100)
endif()
ipsd_add_test(test_ptc_sim ipsinstr) # photon transfer on the simulated bench: 2 % of the truth
