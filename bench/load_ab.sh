#!/usr/bin/env bash
# load_ab.sh [BUILD_DIR]: A/B of ipsd options for the reads' tail while fits run (prints figures,
# never pass/fail). Runs step 3 of bench/load.sh (calibration reads with FITS fits queued) once
# per variant, the variants interleaved, REPS rounds, so that the shared machine's load falls on
# all of them alike; then prints per variant the min and median of p99, reads/s and fits done
# in the window (the fits' throughput is the price of a gentler tail), and the load averages.
# Environment: VARIANTS (';'-separated ipsd option sets, "" the defaults; a set starting with
# @DIR runs the ipsd and ips of build DIR instead, to compare builds; a set starting with FITS=N
# queues N fits instead of FITS, e.g. "FITS=0" for the reads' floor on the machine as it is
# loaded, with no fits running; default compares
# --fit-nice 0/10/19, --fit-batch and --workers 1), REPS (3), and load.sh's FITS, DURATION, CONNS.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
REPS=${REPS:-3}
VARIANTS=${VARIANTS:---fit-nice 0;--fit-nice 10;--fit-nice 19;--fit-nice 19 --fit-batch;--workers 1}
IFS=';' read -r -a variants <<<"$VARIANTS"
out=$(mktemp "${TMPDIR:-/tmp}/ipsd-ab-XXXXXX")
trap 'rm -f "$out"' EXIT
for rep in $(seq "$REPS"); do
    for i in "${!variants[@]}"; do
        v=${variants[$i]}
        label=$v
        b=$build
        fits=${FITS:-300}
        if [[ $v == FITS=* ]]; then
            fits=${v%% *}
            fits=${fits#FITS=}
            [[ $v == *" "* ]] && v=${v#* } || v=
        fi
        if [[ $v == @* ]]; then
            b=${v%% *}
            b=${b#@}
            [[ $v == *" "* ]] && v=${v#* } || v=
        fi
        line=$(FITS=$fits STEPS=3 IPSD_ARGS="$v" bash "$root/bench/load.sh" "$b" | grep '^summary:')
        echo "round $rep [$label] $line"
        printf '%d\t%s\n' "$i" "$line" >>"$out"
    done
done
python3 - "$out" "${variants[@]}" <<'PY'
import re, statistics, sys
rows = {}
for l in open(sys.argv[1]):
    i, text = l.rstrip("\n").split("\t", 1)
    m = re.search(r"summary: ([\d.]+) reads/s, p50 ([\d.]+) ms, p99 ([\d.]+) ms; (\d+) fits finished"
                  r".*?load average ([\d.]+)", text)
    if m: rows.setdefault(int(i), []).append([float(x) for x in m.groups()])
print("%-32s %5s %16s %16s %12s %10s" % ("ipsd options", "runs", "p99 ms min/med",
                                         "reads/s min/med", "fits min/med", "load 1min"))
for i, v in enumerate(sys.argv[2:]):
    r = rows.get(i, [])
    if not r: continue
    col = lambda k: [x[k] for x in r]
    mm = lambda k, f: ("%s/%s" % (f % min(col(k)), f % statistics.median(col(k))))
    print("%-32s %5d %16s %16s %12s %10s" % (v or "(defaults)", len(r), mm(2, "%.1f"), mm(0, "%.0f"),
                                             mm(3, "%d"), "%.1f-%.1f" % (min(col(4)), max(col(4)))))
PY
