#!/usr/bin/env bash
# build-matrix.sh [--incremental] [NAME...]: builds ipsd in every configuration a packager or
# developer uses, each from scratch into build-matrix/NAME, with -DIPSD_WERROR=ON and libcamera
# auto, and fails on the first warning (compiler, linker or CMake: -Werror alone does not cover
# the last two). --incremental keeps what an earlier run built (scripts/test.sh uses it: a
# compiler warning is an error under -Werror, so it cannot hide in an object kept from before).
# NAMEs (default: all, in this order):
#   gcc-release  gcc-debug  gcc-relwithdebinfo  clang-release
# JOBS sets the parallel build jobs (default: nproc). Prints each configuration's time.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
scripts/deps.sh # clang among them

declare -A build_type=([gcc-release]=Release [gcc-debug]=Debug
                       [gcc-relwithdebinfo]=RelWithDebInfo [clang-release]=Release)
declare -A cc=([gcc-release]=gcc [gcc-debug]=gcc [gcc-relwithdebinfo]=gcc [clang-release]=clang)
declare -A cxx=([gcc-release]=g++ [gcc-debug]=g++ [gcc-relwithdebinfo]=g++
                [clang-release]=clang++)
incremental=0
if [[ ${1:-} == --incremental ]]; then
    incremental=1
    shift
fi
names=("$@")
((${#names[@]})) || names=(gcc-release gcc-debug gcc-relwithdebinfo clang-release)
jobs=${JOBS:-$(nproc)}

start_all=$SECONDS
for name in "${names[@]}"; do
    [[ -n "${build_type[$name]:-}" ]] || { echo "build-matrix: unknown configuration '$name'" >&2; exit 2; }
    dir=build-matrix/$name
    ((incremental)) || rm -rf "$dir"
    mkdir -p "$dir"
    start=$SECONDS
    echo "== $name (${cc[$name]}, ${build_type[$name]})"
    if ! { cmake -S "$root" -B "$dir" -DCMAKE_BUILD_TYPE="${build_type[$name]}" -DIPSD_WERROR=ON \
                 -DIPSD_WITH_LIBCAMERA=auto -DCMAKE_C_COMPILER="${cc[$name]}" \
                 -DCMAKE_CXX_COMPILER="${cxx[$name]}" &&
           cmake --build "$dir" -j"$jobs"; } >"$dir/build.log" 2>&1; then
        cat "$dir/build.log"
        echo "build-matrix: $name failed (log: $dir/build.log)" >&2
        exit 1
    fi
    # anything -Werror lets through: linker warnings, CMake warnings
    if grep -nE '[Ww]arning:|CMake Warning' "$dir/build.log"; then
        echo "build-matrix: $name printed a warning (log: $dir/build.log)" >&2
        exit 1
    fi
    echo "   ok in $((SECONDS - start)) s"
done
echo "build-matrix: ${#names[@]} configuration(s) warning-free in $((SECONDS - start_all)) s"
