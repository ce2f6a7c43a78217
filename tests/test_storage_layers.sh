#!/usr/bin/env bash
# test_storage_layers.sh NM LIBIPSSTORE STORAGE_DIR: the layering of storage/ that docs/schema.md
# ("The code") describes, read from the built library and the sources, not from the code's own
# claims. Asserts: (1) the calls between the files of libipsstore, taken from the archive's symbol
# tables with nm (a file that uses a symbol another file defines calls it), have no cycle
# (tsort finds none) and are exactly the documented ones; (2) each table's file prepares only
# the statements of its own table (STG_<TABLE>_* ids), and storage_compose.c none.
set -euo pipefail
nm=$1
lib=$2
src=$3
fail=0
bad() { echo "FAIL: $*" >&2; fail=1; }

# "caller callee" pairs, one per line, between distinct objects of the archive
edges=$("$nm" -A "$lib" | awk '
    { split($1, p, ":"); obj = p[2]; sub(/\.o$/, "", obj); sym = $NF; type = $(NF - 1) }
    type ~ /^[TDRB]$/ { def[sym] = obj }
    type == "U" { use[obj " " sym] = 1 }
    END {
        for (k in use) {
            split(k, u, " ")
            if ((u[2] in def) && def[u[2]] != u[1]) print u[1], def[u[2]]
        }
    }' | sort -u)
echo "calls between the files of storage/:"
echo "$edges" | sed 's/^/  /'
[ -n "$edges" ] || bad "no calls found: is $lib a static archive of storage/?"

# (1a) no cycle: tsort fails on a loop
if ! echo "$edges" | tsort >/dev/null 2>"${TMPDIR:-/tmp}/tsort.$$"; then
    bad "the files of storage/ call each other in a cycle: $(cat "${TMPDIR:-/tmp}/tsort.$$")"
fi
rm -f "${TMPDIR:-/tmp}/tsort.$$"

# (1b) exactly the documented calls (docs/schema.md, "The code"): keep the two in step
want='storage.c storage_gate.c
storage_gate.c sqldb.c
storage_gate.c storage_listen.c
storage_listen.c sqldb_pg.c
storage_listen.c storage_sql_pg.c
storage_backup.c storage.c
storage_copy.c storage.c
storage_backup.c sqldb_sqlite.c
storage.c storage_sql.c
storage.c storage_sql_pg.c
storage.c sqldb.c
storage.c sqldb_sqlite.c
sqldb.c sqldb_sqlite.c
sqldb.c sqldb_pg.c
storage_calib.c storage.c
storage_calib.c storage_gate.c
storage_calib.c storage_sensor.c
storage_compose.c storage.c
storage_compose.c storage_calib.c
storage_compose.c storage_fit.c
storage_compose.c storage_job.c
storage_compose.c storage_ptc.c
storage_compose.c storage_scan.c
storage_fit.c storage.c
storage_fit.c storage_scan.c
storage_frame.c storage.c
storage_frame.c storage_scan.c
storage_job.c storage.c
storage_job.c storage_scan.c
storage_ptc.c storage.c
storage_scan.c storage.c
storage_scan.c storage_sensor.c
storage_sensor.c storage.c'
if [ "$edges" != "$(echo "$want" | sort -u)" ]; then
    bad "the calls differ from the documented ones:"
    diff <(echo "$want" | sort -u) <(echo "$edges") >&2 || true
fi

# (2) statement ids by table prefix: storage_<t>.c uses only STG_<T>_*
for f in sensor scan frame job fit calib compose ptc; do
    file="$src/storage_$f.c"
    [ -f "$file" ] || { bad "$file is missing"; continue; }
    own=$(echo "$f" | tr a-z A-Z)
    others=$(grep -oE 'STG_(SENSOR|SCAN|FRAME|JOB|FIT|CALIB|PTC)_[A-Z_]+' "$file" |
             grep -v "^STG_${own}_" | sort -u | tr '\n' ' ' || true)
    [ -z "$others" ] || bad "storage_$f.c prepares other tables' statements: $others"
done

[ "$fail" -eq 0 ] && echo "storage layers: ok"
exit "$fail"
