# Tests of the scan-file module (instrument/scanfile) and of the `ips` command-line tool.
ipsd_add_test(test_scanfile ipsinstr)

if(TARGET ips)
    add_test(NAME test_cli
             COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_cli.sh $<TARGET_FILE:ips>
             WORKING_DIRECTORY ${IPSD_TEST_DATA})
    add_test(NAME test_cli_bench
             COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_cli.sh $<TARGET_FILE:ips> bench
             WORKING_DIRECTORY ${IPSD_TEST_DATA})
    # busy 2-core machine, ASan build: 134 s and 191 s (optimised: 80 s, 59 s); 4x
    set_tests_properties(test_cli PROPERTIES TIMEOUT 540)
    set_tests_properties(test_cli_bench PROPERTIES TIMEOUT 780)
    # --region and the whole-raster Wiener: 3 s optimised; ASan on a busy machine well under 60 s
    add_test(NAME test_fit_region
             COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_fit_region.sh $<TARGET_FILE:ips>
             WORKING_DIRECTORY ${IPSD_TEST_DATA})
    set_tests_properties(test_fit_region PROPERTIES TIMEOUT 240)
endif()

find_package(Python3 COMPONENTS Interpreter)
# A Python test of the ips binary: tests/NAME.py IPS, run in the test data directory, within
# TIMEOUT seconds (0: CTest's default).
function(ips_python_test name timeout)
    if(TARGET ips AND Python3_Interpreter_FOUND)
        add_test(NAME ${name}
                 COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/${name}.py
                         $<TARGET_FILE:ips>
                 WORKING_DIRECTORY ${IPSD_TEST_DATA})
        if(timeout GREATER 0)
            set_tests_properties(${name} PROPERTIES TIMEOUT ${timeout})
        endif()
    endif()
endfunction()

# `ips fit --pixels all` on an `ips simulate --write-subframe` scan: every covered pixel against
# the simulator's truth, the POI against ips fit, bad subframes (16 s optimised at load 11;
# ASan at load 26 over 300 s)
ips_python_test(test_fit_pixels 1200)
# the fit document's shrunk_map against the formula by hand and the simulator's truth (~1 s)
ips_python_test(test_fit_shrunk 0)
# `ips fit --krige`: the kriged map against the simulator's truth and the recommended map (~5 s)
ips_python_test(test_fit_kriged 300)
# `ips simulate --adaptive` against the simulator's truth and a raster of as many points, and its
# stop on a target against the truth (~17 s)
ips_python_test(test_simulate_adaptive 240)
# output files never replace a link, a FIFO or a device (base/outfile.h; a few s)
ips_python_test(test_cli_outfile 120)

# `ips ptc --sim`: gain and read noise against the simulator's truth, bad input (~3 s optimised)
if(TARGET ips)
    add_test(NAME test_cli_ptc
             COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_cli_ptc.sh $<TARGET_FILE:ips>
             WORKING_DIRECTORY ${IPSD_TEST_DATA})
    set_tests_properties(test_cli_ptc PROPERTIES TIMEOUT 120)
endif()
# the geometry fit's r picked from the data: recovered R, dx, dy against the simulator's truth on
# structured pixels, and poor_fit at a map too coarse (~6 s optimised)
ips_python_test(test_fit_geometry_pick 240)
# the geometry refined under the kriged model: R, dx, dy against the simulator's truth on an edge
# and a dead-corner pixel, poor_fit under a noise model 5x too small, bad options (~12 s optimised)
ips_python_test(test_fit_geometry_kriged 300)
