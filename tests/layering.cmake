# The rooms' include directions (docs/architecture.md), checked over the sources.
add_test(NAME test_layering
         COMMAND python3 ${CMAKE_CURRENT_SOURCE_DIR}/test_layering.py ${PROJECT_SOURCE_DIR})
set_tests_properties(test_layering PROPERTIES TIMEOUT 60)
