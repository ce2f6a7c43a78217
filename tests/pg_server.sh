#!/usr/bin/env bash
# pg_server.sh: a throwaway PostgreSQL server for the tests of storage/'s PostgreSQL backend
# (tests/pg.cmake), on loopback only.
#
#   tests/pg_server.sh start DIR   makes a new cluster in DIR/data (initdb) and starts it on
#                                  127.0.0.1 and a free port, its unix socket in DIR; writes
#                                  DIR/uri (postgresql://ipsd_writer@127.0.0.1:PORT/ipsd, no
#                                  password) and DIR/pgpass (PGPASSFILE=DIR/pgpass), prints the
#                                  URI. A DIR whose server runs: prints its URI and does nothing.
#                                  With openssl, the server also speaks TLS: its self-signed
#                                  certificate for 127.0.0.1 is DIR/root.crt (a client's
#                                  sslrootcert for sslmode=verify-full), and DIR/other-root.crt
#                                  is a certificate the server's does not chain to.
#   tests/pg_server.sh stop DIR    stops the server (fast: open connections are closed) and removes DIR
#   tests/pg_server.sh restart DIR stops it (its clients cut off) and starts it again on the same port
#
# The database ipsd belongs to ipsd_writer (LOGIN, password); ipsd_reader (LOGIN, password) may
# only read what ipsd_writer makes. The superuser "postgres" has a generated password
# (DIR/superuser-password) but is reached through the unix socket, where local connections are
# trusted; TCP connections need a password (scram-sha-256).
# PostgreSQL refuses to run as root: as root (CI), initdb and the server run as the system user
# ipsdpg, made when missing. Exit 77 (ctest's skip) when PostgreSQL's binaries are absent
# (IPSD_PG_BINDIR, when set, is the only place looked at).
set -euo pipefail

PG_USER=ipsdpg
START_ATTEMPTS=5      # a free port can be taken between choosing it and the server binding it
READY_TIMEOUT_S=120   # pg_ctl's wait: on a busy 2-core machine a start takes a few seconds

say() { echo "pg_server.sh: $*" >&2; }
die() {
    say "$*"
    exit 1
}
usage() { die "usage: $0 start|stop|restart DIR"; }

(($# == 2)) || usage
cmd=$1
dir_arg=$2
[[ -n "$dir_arg" ]] || usage
case "$cmd" in start | stop | restart) ;; *) usage ;; esac

# PostgreSQL's server binaries: IPSD_PG_BINDIR when set (only there), else Debian's PostgreSQL
# 15, else pg_config's, else the PATH's.
find_bindir() {
    local d dirs
    if [[ -n "${IPSD_PG_BINDIR+set}" ]]; then
        dirs=("$IPSD_PG_BINDIR")
    else
        dirs=(/usr/lib/postgresql/15/bin "$(pg_config --bindir 2>/dev/null || true)"
            "$(dirname "$(command -v initdb 2>/dev/null || echo /nonexistent/initdb)")")
    fi
    for d in "${dirs[@]}"; do
        if [[ -n "$d" && -x "$d/initdb" && -x "$d/pg_ctl" && -x "$d/postgres" &&
            -x "$d/pg_isready" && -x "$d/psql" ]]; then
            echo "$d"
            return 0
        fi
    done
    return 1
}
BIN=$(find_bindir || true)

# RUN: how PostgreSQL's binaries are run (as ipsdpg when we are root).
RUN=()
if [[ $(id -u) -eq 0 ]]; then
    if command -v runuser >/dev/null; then
        RUN=(runuser -u "$PG_USER" --)
    else
        RUN=(setpriv "--reuid=$PG_USER" "--regid=$PG_USER" --init-groups --)
    fi
fi
ensure_pg_user() {
    [[ $(id -u) -eq 0 ]] || return 0
    id -u "$PG_USER" >/dev/null 2>&1 && return 0
    # two starts at once may both try: the user existing afterwards is what counts
    useradd --system --no-create-home --home-dir /nonexistent --shell /usr/sbin/nologin \
        --user-group "$PG_USER" 2>/dev/null || true
    id -u "$PG_USER" >/dev/null 2>&1 || die "cannot create the system user $PG_USER"
}

# DIR as an absolute path (it may not exist yet); never the root or an empty path, since stop
# removes it.
abs_dir() {
    local d=$1
    [[ "$d" == /* ]] || d="$PWD/$d"
    d=$(realpath -m -- "$d")
    [[ "$d" != / && -n "$d" ]] || die "refusing DIR '$1'"
    echo "$d"
}
DIR=$(abs_dir "$dir_arg")

# The directory holding data/ and the socket: DIR, unless the server's user cannot reach it (a
# DIR under root's 0700 home) or the socket's path would be too long for a unix socket (107
# bytes); then a private directory under /tmp, named in DIR/rundir (DIR/data links to it).
run_dir() {
    if [[ -f "$DIR/rundir" ]]; then cat "$DIR/rundir"; else echo "$DIR"; fi
}

# Stops the server of run directory $1 if one runs there (fast, else immediate).
stop_server() {
    local rt=$1
    [[ -n "$BIN" && -f "$rt/data/postmaster.pid" ]] || return 0
    "${RUN[@]}" "$BIN/pg_ctl" status -D "$rt/data" >/dev/null 2>&1 || return 0 # it died
    "${RUN[@]}" "$BIN/pg_ctl" stop -D "$rt/data" -m fast -w -t 60 >/dev/null 2>&1 ||
        "${RUN[@]}" "$BIN/pg_ctl" stop -D "$rt/data" -m immediate -w -t 60 >/dev/null 2>&1 ||
        say "warning: the server of $rt/data did not stop"
}

# Only a DIR this script made (its mark inside), or an empty one, is stopped and removed.
MARK=.ipsd-pg-server
check_ours() {
    if [[ ! -e "$DIR/$MARK" && -n "$(ls -A -- "$DIR" 2>/dev/null)" ]]; then
        die "$DIR is not a directory of pg_server.sh (no $MARK): left as it is"
    fi
}

# Removes DIR and its run directory (only one this script made).
remove_dirs() {
    local rt
    rt=$(run_dir)
    if [[ "$rt" != "$DIR" && "$rt" == /tmp/ipsd-pg.* ]]; then rm -rf -- "$rt"; fi
    rm -rf -- "$DIR"
}

server_running() {
    local rt=$1 port
    [[ -n "$BIN" && -f "$DIR/uri" && -f "$DIR/port" ]] || return 1
    port=$(cat "$DIR/port")
    "${RUN[@]}" "$BIN/pg_ctl" status -D "$rt/data" >/dev/null 2>&1 &&
        "$BIN/pg_isready" -q -h 127.0.0.1 -p "$port" -t 5 >/dev/null 2>&1
}

# restart: the running server of DIR stopped (fast: its clients' connections are cut, as when a
# lab's server restarts) and started again on the same port and data, ready before it returns
if [[ "$cmd" == restart ]]; then
    check_ours
    [[ -n "$BIN" && -f "$DIR/port" ]] || die "no server of pg_server.sh in $DIR"
    rt=$(run_dir)
    "${RUN[@]}" "$BIN/pg_ctl" restart -D "$rt/data" -m fast -l "$rt/log" \
        -o "-p $(cat "$DIR/port")" -w -t "$READY_TIMEOUT_S" >/dev/null ||
        die "the server of $DIR did not restart (log: $rt/log)"
    server_running "$rt" || die "the server of $DIR is not ready after its restart"
    exit 0
fi

if [[ "$cmd" == stop ]]; then
    [[ -e "$DIR" ]] || exit 0
    check_ours
    stop_server "$(run_dir)"
    remove_dirs
    exit 0
fi

# ---- start ----------------------------------------------------------------------------------
if [[ -z "$BIN" ]]; then
    say "PostgreSQL's binaries (initdb, pg_ctl, postgres, pg_isready, psql) not found: skipped"
    exit 77
fi
t0=$(date +%s%N)

if [[ -e "$DIR" ]]; then
    check_ours
    if server_running "$(run_dir)"; then
        cat "$DIR/uri"
        exit 0
    fi
    # a stale DIR (a server gone, or a start that failed half way): begin again
    stop_server "$(run_dir)"
    remove_dirs
fi

ensure_pg_user
mkdir -p -- "$DIR"
: >"$DIR/$MARK"
RT=$DIR
if [[ $(id -u) -eq 0 ]]; then
    chown "$PG_USER:" "$DIR"
    if ! "${RUN[@]}" test -w "$DIR" -a -x "$DIR"; then RT=; fi
fi
# ".s.PGSQL.65535.lock" is the longest name the server makes in the socket's directory
if [[ -n "$RT" ]] && ((${#RT} + 21 > 107)); then RT=; fi
if [[ -z "$RT" ]]; then
    RT=$(mktemp -d /tmp/ipsd-pg.XXXXXX)
    [[ $(id -u) -eq 0 ]] && chown "$PG_USER:" "$RT"
    echo "$RT" >"$DIR/rundir"
    ln -s "$RT/data" "$DIR/data"
fi
DATA=$RT/data

# on a failure from here: no server is left running (DIR stays, with the log, until stop)
started=0
on_exit() {
    local rc=$?
    if ((rc != 0)); then
        [[ -f "$RT/log" ]] && { say "server log (last lines):"; tail -n 20 "$RT/log" >&2; }
        ((started)) && stop_server "$RT"
    fi
    exit "$rc"
}
trap on_exit EXIT

new_password() { od -An -tx1 -N16 /dev/urandom | tr -d ' \n'; }

umask 077
new_password >"$RT/superuser-password"
[[ $(id -u) -eq 0 ]] && chown "$PG_USER:" "$RT/superuser-password"
# --no-sync and fsync=off: a throwaway cluster, not worth a disk flush (a busy CI machine's
# disks are slow); C collation: text compares byte by byte, as in SQLite
"${RUN[@]}" "$BIN/initdb" -D "$DATA" -U postgres --pwfile="$RT/superuser-password" \
    --auth-local=trust --auth-host=scram-sha-256 -E UTF8 --locale=C --no-sync \
    --no-instructions >"$RT/initdb.log" 2>&1 ||
    { cat "$RT/initdb.log" >&2; die "initdb failed"; }
[[ "$RT" != "$DIR" ]] && ln -sf "$RT/superuser-password" "$DIR/superuser-password"
sq_dir=${RT//\'/\'\'}
"${RUN[@]}" tee -a "$DATA/postgresql.conf" >/dev/null <<EOF

# tests/pg_server.sh: loopback only, the socket beside the data, no durability
listen_addresses = '127.0.0.1'
unix_socket_directories = '$sq_dir'
fsync = off
synchronous_commit = off
full_page_writes = off
EOF

# TLS with a self-signed certificate for 127.0.0.1 (an EC key: made in milliseconds), when
# openssl is there; a second one the server does not use, for a client that must refuse it
if command -v openssl >/dev/null; then
    for name in server other; do
        openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 30 \
            -subj "/CN=127.0.0.1" -addext "subjectAltName=IP:127.0.0.1" \
            -keyout "$RT/$name.key" -out "$RT/$name.crt" >/dev/null 2>&1 ||
            die "openssl could not make the test server's certificate"
    done
    cp "$RT/server.crt" "$DIR/root.crt"
    cp "$RT/other.crt" "$DIR/other-root.crt"
    chmod 644 "$DIR/root.crt" "$DIR/other-root.crt"
    if [[ $(id -u) -eq 0 ]]; then chown "$PG_USER:" "$RT/server.key" "$RT/server.crt"; fi
    "${RUN[@]}" tee -a "$DATA/postgresql.conf" >/dev/null <<EOF
ssl = on
ssl_cert_file = '$sq_dir/server.crt'
ssl_key_file = '$sq_dir/server.key'
EOF
fi

# a port the kernel says is free now (without python3: a random one; a taken one is retried)
free_port() {
    python3 -c 'import socket
s = socket.socket()
s.bind(("127.0.0.1", 0))
print(s.getsockname()[1])
s.close()' 2>/dev/null || echo $((20000 + RANDOM % 30000))
}

port=
for ((attempt = 1; attempt <= START_ATTEMPTS; attempt++)); do
    p=$(free_port)
    if "${RUN[@]}" "$BIN/pg_ctl" start -D "$DATA" -l "$RT/log" -o "-p $p" -w \
        -t "$READY_TIMEOUT_S" >/dev/null 2>&1; then
        port=$p
        break
    fi
    say "start on port $p failed (attempt $attempt of $START_ATTEMPTS)"
    # a server that did start but was not ready in time must not stay behind
    stop_server "$RT"
done
[[ -n "$port" ]] || die "the server did not start (log: $RT/log)"
started=1
echo "$port" >"$DIR/port"

# ready for TCP clients: pg_ctl's wait reads the postmaster's state; this asks the server
deadline=$(($(date +%s) + READY_TIMEOUT_S))
until "$BIN/pg_isready" -q -h 127.0.0.1 -p "$port" -d postgres -t 5; do
    (($(date +%s) < deadline)) ||
        die "the server on port $port is not ready after ${READY_TIMEOUT_S} s"
    sleep 0.1
done

writer_pw=$(new_password)
reader_pw=$(new_password)
# as the superuser, through the socket (trusted); passwords are hex, safe inside quotes
"${RUN[@]}" "$BIN/psql" -X -q -v ON_ERROR_STOP=1 -h "$RT" -p "$port" -U postgres -d postgres \
    >/dev/null <<EOF
CREATE ROLE ipsd_writer LOGIN PASSWORD '$writer_pw';
CREATE ROLE ipsd_reader LOGIN PASSWORD '$reader_pw';
ALTER ROLE ipsd_reader SET default_transaction_read_only = on;
CREATE DATABASE ipsd OWNER ipsd_writer;
\connect ipsd
-- whatever the writer makes, in any schema, the reader may read
ALTER DEFAULT PRIVILEGES FOR ROLE ipsd_writer GRANT USAGE ON SCHEMAS TO ipsd_reader;
ALTER DEFAULT PRIVILEGES FOR ROLE ipsd_writer GRANT SELECT ON TABLES TO ipsd_reader;
ALTER DEFAULT PRIVILEGES FOR ROLE ipsd_writer GRANT SELECT ON SEQUENCES TO ipsd_reader;
EOF

# the client's files, the invoking user's (0600: libpq ignores a password file others can read)
printf '127.0.0.1:%s:ipsd:ipsd_writer:%s\n127.0.0.1:%s:ipsd:ipsd_reader:%s\n' \
    "$port" "$writer_pw" "$port" "$reader_pw" >"$DIR/pgpass.tmp"
chmod 600 "$DIR/pgpass.tmp"
mv -f "$DIR/pgpass.tmp" "$DIR/pgpass"
uri="postgresql://ipsd_writer@127.0.0.1:$port/ipsd"
# the writer through TCP with its password: what the tests will do
PGPASSFILE="$DIR/pgpass" "$BIN/psql" -X -q -w -At -d "$uri" -c 'SELECT 1' >/dev/null ||
    die "ipsd_writer cannot log in through $uri"
umask 022
echo "$uri" >"$DIR/uri.tmp"
mv -f "$DIR/uri.tmp" "$DIR/uri" # last: a DIR with a uri has a server ready for it

ms=$((($(date +%s%N) - t0) / 1000000))
say "PostgreSQL $("$BIN/postgres" --version | awk '{print $3}') on 127.0.0.1:$port," \
    "data $DATA, ready in $((ms / 1000)).$(printf '%03d' $((ms % 1000))) s"
echo "$uri"
