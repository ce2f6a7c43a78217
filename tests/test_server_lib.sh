# test_server_lib.sh: helpers the HTTP tests of ipsd source: a real daemon on a free loopback port
# (--listen 127.0.0.1:0, the port read back from --port-file) with a database in a temporary
# directory, a real client (curl), JSON checks with python3's standard library, and row counts
# with the sqlite3 shell. Usage: source it, then `setup IPSD IPS`.
set -uo pipefail

FAILS=0
CHECKS=0
PID=
PORT=
T=

# ok COND_STATUS MESSAGE: counts a check; prints the message when it failed.
ok() {
    CHECKS=$((CHECKS + 1))
    if [[ $1 != 0 ]]; then
        FAILS=$((FAILS + 1))
        echo "FAIL: $2" >&2
    fi
}
check() { # check MESSAGE -- COMMAND...: runs the command, counts it as a check
    local msg=$1
    shift 2
    "$@"
    ok $? "$msg"
}

setup() {
    IPSD=$1
    IPS=${2:-}
    T=$(mktemp -d "${TMPDIR:-/tmp}/ipsd-http-XXXXXX")
    trap cleanup EXIT
}

cleanup() {
    if [[ -n $PID ]] && kill -0 "$PID" 2>/dev/null; then
        kill -9 "$PID" 2>/dev/null
        wait "$PID" 2>/dev/null
    fi
    [[ -n $T ]] && rm -rf "$T"
}

# start [ipsd options...]: starts ipsd on $T/ipsd.db (unless --db is given), waits for its port.
start() {
    rm -f "$T/port"
    "$IPSD" --listen 127.0.0.1:0 --port-file "$T/port" --db "$T/ipsd.db" --heartbeat 1 "$@" \
        >>"$T/ipsd.log" 2>&1 &
    PID=$!
    for _ in $(seq 200); do
        [[ -s $T/port ]] && break
        kill -0 "$PID" 2>/dev/null || break
        sleep 0.05
    done
    PORT=$(cat "$T/port" 2>/dev/null)
    if [[ -z $PORT ]]; then
        echo "ipsd did not start:" >&2
        cat "$T/ipsd.log" >&2
        exit 1
    fi
    BASE=http://127.0.0.1:$PORT
}

# stop_term: SIGTERM, waits, returns ipsd's exit status.
stop_term() {
    kill -TERM "$PID"
    wait "$PID"
    local rc=$?
    PID=
    return $rc
}

# stop_kill: kill -9 (a crash), waits.
stop_kill() {
    kill -9 "$PID"
    wait "$PID" 2>/dev/null
    PID=
}

# req METHOD PATH [BODY [extra curl args...]]: sets STATUS and BODY (the response). A BODY of
# @FILE sends the file's content.
req() {
    local method=$1 path=$2 body=${3:-}
    shift 3 2>/dev/null || shift $#
    local args=(-s -o "$T/body" -w '%{http_code}' -X "$method" "$@")
    if [[ -n $body ]]; then
        args+=(-H 'Content-Type: application/json' --data-binary "$body")
    fi
    STATUS=$(curl "${args[@]}" "$BASE$path")
    BODY=$(cat "$T/body")
}

# js EXPR: evaluates a python expression over the last BODY parsed as JSON (as `d`).
js() {
    python3 -c "import json,sys; d=json.loads(sys.stdin.read()); print(($1))" <<<"$BODY"
}

# expect_status WANT MESSAGE
expect_status() {
    [[ $STATUS == "$1" ]]
    ok $? "$2: status $STATUS, want $1 (body: ${BODY:0:300})"
}

# expect_error STATUS FIELD MESSAGE: an error body with that status and field ("" for none), and
# a code and a message.
expect_error() {
    expect_status "$1" "$3"
    local got
    got=$(js "d['error'].get('field', '') + '|' + str(bool(d['error']['code'] and d['error']['message']))" 2>/dev/null)
    [[ $got == "$2|True" ]]
    ok $? "$3: error field|has code and message = '$got', want '$2|True' (body: ${BODY:0:300})"
}

# sql QUERY: the sqlite3 shell's answer on the test database (an independent reader).
sql() { sqlite3 "$T/ipsd.db" "$1"; }

# wait_job ID STATE [SECONDS]: polls GET /api/jobs/ID until its state is STATE.
wait_job() {
    local id=$1 want=$2 limit=${3:-60} state=
    for _ in $(seq $((limit * 10))); do
        req GET "/api/jobs/$id"
        state=$(js "d['state']" 2>/dev/null)
        [[ $state == "$want" ]] && return 0
        sleep 0.1
    done
    echo "job $id is '$state', not '$want' after ${limit}s" >&2
    return 1
}

finish() {
    echo "$CHECKS checks, $FAILS failed"
    [[ $FAILS == 0 ]]
}
