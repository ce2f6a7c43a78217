#!/usr/bin/env bash
# build.sh DIR [cmake options...]: configures and builds ipsd into DIR (idempotent, incremental).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
dir=$1
shift
cmake -S "$root" -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@" >/dev/null
cmake --build "$dir" -j"$(nproc)"
