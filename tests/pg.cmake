# tests/pg.cmake: storage/'s SQL on a real PostgreSQL server, a throwaway one on 127.0.0.1 that
# tests/pg_server.sh starts for the tests of the fixture "pg" (data, socket, URI and password
# file in build/pg):
#   pg_server_start  FIXTURES_SETUP pg: `pg_server.sh start build/pg` (initdb, start, roles)
#   pg_sql_check     every statement of storage/ prepares on the server, the migrations make the
#                    schema, a bad JSON document breaks its CHECK, and a script of statements
#                    gives what SQLite gives (tests/pg_sql_check.py)
#   pg_server_stop   FIXTURES_CLEANUP pg: stops the server and removes build/pg
# Without PostgreSQL's binaries (Debian: postgresql, scripts/deps.sh) the start and the check
# skip (exit 77). A test of the fixture reads the URI from build/pg/uri and finds the password
# through PGPASSFILE=build/pg/pgpass.
find_package(Python3 COMPONENTS Interpreter)
if(NOT Python3_Interpreter_FOUND)
    message(STATUS "PostgreSQL tests: python3 not found, not registered")
    return()
endif()

set(IPSD_PG_DIR ${CMAKE_BINARY_DIR}/pg)
add_test(NAME pg_server_start
         COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/pg_server.sh start ${IPSD_PG_DIR})
add_test(NAME pg_server_stop
         COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/pg_server.sh stop ${IPSD_PG_DIR})
# the check builds a tiny program printing the SQL texts with the project's compiler
add_test(NAME pg_sql_check
         COMMAND ${Python3_EXECUTABLE} -B ${CMAKE_CURRENT_SOURCE_DIR}/pg_sql_check.py
                 --uri-file ${IPSD_PG_DIR}/uri)
# start: 2-3 s (busy 2-core machine: 3.3-6.4 s, initdb most of it; the server's own wait is up
# to 120 s an attempt, 5 attempts when ports are taken); stop: 0.2-0.3 s; the check: 1.4-1.8 s
# (busy: about 2 s)
set_tests_properties(pg_server_start PROPERTIES FIXTURES_SETUP pg SKIP_RETURN_CODE 77
                     TIMEOUT 300)
set_tests_properties(pg_server_stop PROPERTIES FIXTURES_CLEANUP pg TIMEOUT 120)
set_tests_properties(pg_sql_check PROPERTIES FIXTURES_REQUIRED pg SKIP_RETURN_CODE 77
    ENVIRONMENT "PGPASSFILE=${IPSD_PG_DIR}/pgpass;CC=${CMAKE_C_COMPILER}")
