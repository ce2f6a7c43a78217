#!/usr/bin/env bash
# build.sh DIR [cmake options...]: configures and builds ipsd into DIR (idempotent, incremental).
# The compiler's output goes to DIR/build.log and is shown only when the build fails.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
dir=$1
shift
mkdir -p "$dir"
echo "ipsd: building in $dir"
if ! { cmake -S "$root" -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DIPSD_WERROR=ON "$@" &&
       cmake --build "$dir" -j"$(nproc)"; } >"$dir/build.log" 2>&1; then
    cat "$dir/build.log"
    echo "ipsd: build failed (log: $dir/build.log)" >&2
    exit 1
fi
