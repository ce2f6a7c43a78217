# README.md's `ips` commands, run as the README shows them (tests/test_readme.py; a few seconds
# optimised, the kriged fit the longest).
if(TARGET ips)
    add_test(NAME test_readme
             COMMAND python3 -B ${CMAKE_CURRENT_SOURCE_DIR}/test_readme.py $<TARGET_FILE:ips>
                     ${PROJECT_SOURCE_DIR})
    set_tests_properties(test_readme PROPERTIES TIMEOUT 300)
endif()
