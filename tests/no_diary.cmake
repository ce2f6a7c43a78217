# The tracked text speaks of the product alone: no account of how the work went (its periods,
# its tracker's numbers, the people, the days) in the code, its comments or its documents
# (tests/test_no_diary.py has the words). Needs git: it reads the tracked files of the checkout
# the build was configured from.
add_test(NAME test_no_diary
         COMMAND python3 -B ${CMAKE_CURRENT_SOURCE_DIR}/test_no_diary.py ${PROJECT_SOURCE_DIR})
set_tests_properties(test_no_diary PROPERTIES TIMEOUT 60)
