#!/usr/bin/env bash
# web-deps.sh: installs the dashboard's plotting library (Plotly.js, pinned by web/package-lock.json)
# into web/node_modules, where ipsd serves it from (docs/web.md). Idempotent and offline-safe: it
# runs `npm ci` only when web/node_modules was not installed from the current lock file (a copy of
# the lock is kept as web/node_modules/.ipsd-lock), so a lab without network keeps what it has.
# When npm cannot install it the dashboard still works, and its figures say how to install it.
#   scripts/web-deps.sh            used by run.sh; a failed install is a warning
#   scripts/web-deps.sh --strict   used by test.sh; a failed install is an error
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
web=$root/web
stamp=$web/node_modules/.ipsd-lock
if [[ -f $stamp ]] && cmp -s "$stamp" "$web/package-lock.json"; then
    exit 0
fi
echo "ipsd: installing the dashboard's plotting library (npm ci --prefix web)"
if npm ci --prefix "$web" --no-audit --no-fund --loglevel=error; then
    cp "$web/package-lock.json" "$stamp"
elif [[ ${1:-} == --strict ]]; then
    echo "ipsd: npm ci --prefix web failed" >&2
    exit 1
else
    echo "ipsd: warning: npm ci --prefix web failed (no npm registry?): the dashboard runs without" \
        "its plots until it is installed" >&2
fi
