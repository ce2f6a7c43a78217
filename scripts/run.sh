#!/usr/bin/env bash
# run.sh: installs what is missing, builds ipsd, and runs the main job on the embedded default:
# the fit of the reference scan (model selection over r = 1..8, the F-test of the paper's edge
# model, the Wiener baseline), printed as a table.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
scripts/deps.sh
scripts/build.sh build
build/cli/ips fit tests/data/paperlike_scan.json --ftest top,left,bottom --wiener --table
