#!/usr/bin/env bash
# test.sh: installs what is missing, builds ipsd twice (optimised, and with AddressSanitizer +
# UndefinedBehaviorSanitizer) and runs every test in both builds, then fuzzes each parser of outside
# input for a few seconds (clang's libFuzzer under ASan + UBSan: tests/fuzz.cmake, build-fuzz/,
# only the fuzz targets built there; bench/fuzz.sh runs them long); on the way it checks that gcc
# Release and Debug and clang Release build without a warning (scripts/build-matrix.sh). Both
# builds' tests run even when the first set fails, so one run shows everything; exit status 0
# only when all pass.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
scripts/deps.sh

scripts/build.sh build
scripts/build.sh build-asan -DIPSD_SANITIZE=ON
# the fuzz targets only (the rest of the tree is tested in the two builds above)
mkdir -p build-fuzz
if ! { cmake -S "$root" -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DIPSD_WERROR=ON \
             -DCMAKE_C_COMPILER=clang -DIPSD_FUZZ=ON &&
       cmake --build build-fuzz -j"$(nproc)" --target ipsd_fuzz; } >build-fuzz/build.log 2>&1; then
    cat build-fuzz/build.log
    echo "ipsd: fuzz build failed (log: build-fuzz/build.log)" >&2
    exit 1
fi
# the other configurations packagers use must build warning-free too (build is gcc RelWithDebInfo)
scripts/build-matrix.sh --incremental gcc-release gcc-debug clang-release
# the browser test's driver, pinned by tests/web/package-lock.json (the browser is Debian's)
npm ci --prefix tests/web --no-audit --no-fund --loglevel=error
# the OpenAPI checks' tools (Redocly's CLI, ajv), pinned by tests/apilint/package-lock.json
npm ci --prefix tests/apilint --no-audit --no-fund --loglevel=error
# the dashboard's plotting library, pinned by web/package-lock.json (the browser test needs it)
scripts/web-deps.sh --strict

export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
status=0
echo "== tests (optimised build)"
ctest --test-dir build --output-on-failure -j2 || status=1
echo "== tests (AddressSanitizer + UBSan build)"
ctest --test-dir build-asan --output-on-failure -j2 || status=1
echo "== fuzzing (clang libFuzzer + ASan + UBSan, IPSD_FUZZ_SECONDS each)"
ctest --test-dir build-fuzz --output-on-failure -j2 -R '^fuzz_' -E '^fuzz_replay_' || status=1
if ((status)); then echo "ipsd: some tests failed (see above)" >&2; fi
exit $status
