#!/usr/bin/env bash
# build.sh DIR [cmake options...]: configures and builds ipsd into DIR (idempotent, incremental).
# The compiler's output goes to DIR/build.log and is shown only when the build fails.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
dir=$1
shift
mkdir -p "$dir"
echo "ipsd: building in $dir (log: $dir/build.log)"
start=$(date +%s)
# the compiler's output goes to the log; make's percentages are shown as the build goes (a line
# per tenth, or one updated line on a terminal)
progress() {
    local last=-1 pct
    while IFS= read -r line; do
        [[ $line =~ ^\[\ *([0-9]+)%\] ]] || continue
        pct=${BASH_REMATCH[1]}
        if [[ -t 1 ]]; then
            printf '\ripsd: building %3d%%' "$pct"
        elif ((pct / 10 > last / 10)); then
            echo "ipsd: building $pct%"
        fi
        last=$pct
    done
    [[ -t 1 ]] && echo
    return 0
}
set +e
{ cmake -S "$root" -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DIPSD_WERROR=ON "$@" &&
  cmake --build "$dir" -j"$(nproc)"; } 2>&1 | tee "$dir/build.log" | progress
status=${PIPESTATUS[0]}
set -e
if ((status != 0)); then
    cat "$dir/build.log"
    echo "ipsd: build failed (log: $dir/build.log)" >&2
    exit 1
fi
echo "ipsd: built in $(($(date +%s) - start)) s"
