# tests/fuzz.cmake: the fuzz targets of tests/fuzz/ (hostile input), one per parser of
# outside input: the scan-file reader, each JSON request validator of the API, the URL router,
# the query parsing of the list endpoints, base/'s text parsers, the stage string, and the
# POSITIONS table of a FITS scan cube (tests/fuzz/README.md).
#
# Every build (gcc too) builds each target with tests/fuzz/replay.c as fuzz_replay_<target> and
# replays its seed corpus (tests/fuzz/<target>/) and the inputs fuzzing found
# (tests/fuzz/regressions/<target>/) as the ctest fuzz_replay_<target>. With -DIPSD_FUZZ=ON
# (clang) the targets are also linked with libFuzzer as fuzz_<target>, and the ctest
# fuzz_<target> fuzzes each for IPSD_FUZZ_SECONDS under ASan + UBSan, its new inputs kept in the
# build directory (fuzz-corpus/<target>), never in the source tree. bench/fuzz.sh runs them long.
set(IPSD_FUZZ_DIR ${CMAKE_CURRENT_SOURCE_DIR}/fuzz)
set(IPSD_FUZZ_SECONDS 10 CACHE STRING "Seconds each fuzz_<target> ctest fuzzes (IPSD_FUZZ)")
# target:needs-the-API
set(IPSD_FUZZ_TARGETS scanfile:0 text:0 router:1 query:1 sensor_create:1 scan_create:1
                      scan_fit:1 fit_upload:1 promote:1 stage_url:0
                      jitter:1 fits_positions:0)
if(IPSD_FUZZ)
    add_custom_target(ipsd_fuzz) # scripts/test.sh builds only this in the fuzz build
endif()
set(IPSD_FUZZ_WRAP
    -Wl,--wrap=MHD_lookup_connection_value,--wrap=MHD_create_response_from_buffer)
foreach(t ${IPSD_FUZZ_TARGETS})
    string(REPLACE ":" ";" t ${t})
    list(GET t 0 name)
    list(GET t 1 api)
    if(api AND NOT TARGET ipsapi)
        continue()
    endif()
    set(srcs ${IPSD_FUZZ_DIR}/fuzz_${name}.c)
    set(libs ipsbase ipsinstr PkgConfig::JANSSON)
    if(api)
        list(APPEND srcs ${IPSD_FUZZ_DIR}/fuzz_api.c)
        set(libs ipsapi)
    endif()
    set(inputs ${IPSD_FUZZ_DIR}/${name} ${IPSD_FUZZ_DIR}/regressions/${name})
    foreach(kind replay fuzz)
        if(kind STREQUAL "fuzz" AND NOT IPSD_FUZZ)
            continue()
        endif()
        set(exe fuzz_${name})
        if(kind STREQUAL "replay")
            set(exe fuzz_replay_${name})
            add_executable(${exe} ${srcs} ${IPSD_FUZZ_DIR}/replay.c)
        else()
            add_executable(${exe} ${srcs})
            target_link_options(${exe} PRIVATE -fsanitize=fuzzer)
            add_dependencies(ipsd_fuzz ${exe})
        endif()
        target_link_libraries(${exe} PRIVATE ${libs})
        target_include_directories(${exe} PRIVATE ${IPSD_FUZZ_DIR} ${PROJECT_SOURCE_DIR}/api)
        if(api)
            target_link_options(${exe} PRIVATE ${IPSD_FUZZ_WRAP})
        endif()
        if(name STREQUAL "fits_positions")
            target_link_libraries(${exe} PRIVATE ipsexport)
        elseif(name STREQUAL "stage_url")
            # white-box: stage_url.h is internal to instrument/
            target_include_directories(${exe} PRIVATE ${PROJECT_SOURCE_DIR}/instrument)
        endif()
    endforeach()
    add_test(NAME fuzz_replay_${name} COMMAND fuzz_replay_${name} ${inputs})
    set_tests_properties(fuzz_replay_${name} PROPERTIES TIMEOUT ${IPSD_TEST_TIMEOUT})
    if(IPSD_FUZZ)
        set(work ${CMAKE_CURRENT_BINARY_DIR}/fuzz-corpus/${name})
        set(artifacts ${CMAKE_CURRENT_BINARY_DIR}/fuzz-artifacts)
        file(MAKE_DIRECTORY ${work} ${artifacts})
        set(dict)
        if(EXISTS ${IPSD_FUZZ_DIR}/${name}.dict)
            set(dict -dict=${IPSD_FUZZ_DIR}/${name}.dict)
        endif()
        set(existing)
        foreach(d ${inputs})
            if(EXISTS ${d})
                list(APPEND existing ${d})
            endif()
        endforeach()
        # new inputs go to the first directory (the build's); -timeout: a hang is a finding
        add_test(NAME fuzz_${name}
                 COMMAND fuzz_${name} -max_total_time=${IPSD_FUZZ_SECONDS} -timeout=10
                         -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 ${dict}
                         -artifact_prefix=${artifacts}/${name}- ${work} ${existing})
        set_tests_properties(fuzz_${name} PROPERTIES TIMEOUT 300)
    endif()
    if(name STREQUAL "fits_positions")
        # cfitsio asks calloc for as many columns as a broken header seems to say (2e18 once);
        # a refused allocation is its error path, as in ipsd, not a crash of the harness
        set(asan detect_leaks=1:abort_on_error=1:allocator_may_return_null=1)
        set_tests_properties(fuzz_replay_${name} PROPERTIES ENVIRONMENT ASAN_OPTIONS=${asan})
        if(IPSD_FUZZ)
            set_tests_properties(fuzz_${name} PROPERTIES ENVIRONMENT ASAN_OPTIONS=${asan})
        endif()
    endif()
endforeach()
