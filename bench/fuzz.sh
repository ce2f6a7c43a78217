#!/usr/bin/env bash
# fuzz.sh [SECONDS] [TARGET...]: the long runs of the fuzz targets (tests/fuzz/). Builds
# the clang fuzz build (-DIPSD_FUZZ=ON: ASan + UBSan + libFuzzer) into build-fuzz/ (BUILD sets
# another directory) and fuzzes each target SECONDS (default 600) at nice 19, JOBS (default 1) at
# a time, from its seed corpus, its regressions and what earlier runs found (build-fuzz/fuzz-corpus,
# never the source tree). Prints a table: target, executions, seconds, corpus size, crashes.
# A crash, leak, UB report or hang (-timeout=10) is written to build-fuzz/fuzz-artifacts/: fix it,
# then add the input to tests/fuzz/regressions/<target>/ so every build replays it.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
secs=${1:-600}
shift || true
targets=("$@")
((${#targets[@]})) || targets=(scanfile text router query sensor_create scan_create scan_fit
                               fit_upload promote stage_url fits_positions jitter)
build=${BUILD:-$root/build-fuzz}
jobs=${JOBS:-1}
if [[ -z ${NO_BUILD:-} ]]; then
    cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DIPSD_WERROR=ON \
          -DCMAKE_C_COMPILER=clang -DIPSD_FUZZ=ON >/dev/null
    cmake --build "$build" -j"$(nproc)" --target ipsd_fuzz >/dev/null
fi
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
log=$build/fuzz-logs
mkdir -p "$log" "$build/fuzz-artifacts"
run() {
    local t=$1 dict=()
    mkdir -p "$build/fuzz-corpus/$t"
    [[ -f $root/tests/fuzz/$t.dict ]] && dict=(-dict="$root/tests/fuzz/$t.dict")
    local inputs=("$build/fuzz-corpus/$t" "$root/tests/fuzz/$t")
    [[ -d $root/tests/fuzz/regressions/$t ]] && inputs+=("$root/tests/fuzz/regressions/$t")
    # cfitsio may ask calloc for a count a broken header seems to give (tests/fuzz.cmake)
    local asan=$ASAN_OPTIONS
    [[ $t == fits_positions ]] && asan=$asan:allocator_may_return_null=1
    ASAN_OPTIONS=$asan nice -n 19 "$build/tests/fuzz_$t" -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 \
        -max_len=65536 -print_final_stats=1 "${dict[@]}" \
        -artifact_prefix="$build/fuzz-artifacts/$t-" "${inputs[@]}" >"$log/$t.log" 2>&1 || true
}
n=0
for t in "${targets[@]}"; do
    run "$t" &
    if (((++n % jobs) == 0)); then wait; fi
done
wait
printf '%-14s %12s %8s %8s %8s\n' target executions seconds corpus crashes
for t in "${targets[@]}"; do
    f=$log/$t.log
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$f" | tail -1)
    took=$(sed -n 's/^Done [0-9]* runs in \([0-9]*\) second.*/\1/p' "$f" | tail -1)
    corp=$(ls "$build/fuzz-corpus/$t" | wc -l)
    crashes=$(grep -cE '^==[0-9]+==ERROR|runtime error|deadly signal|ALARM: working on the last Unit' "$f" || true)
    printf '%-14s %12s %8s %8s %8s\n' "$t" "${execs:-?}" "${took:-?}" "$corp" "$crashes"
done
ls "$build/fuzz-artifacts"
