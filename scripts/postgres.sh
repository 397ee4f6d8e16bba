#!/usr/bin/env bash
# A throwaway PostgreSQL server for the tests: `bash scripts/postgres.sh COMMAND [ARGS...]` starts one,
# runs COMMAND with GAITSCOPE_TEST_POSTGRES set to its template database's URL, and stops and deletes it
# when COMMAND ends (the exit status is COMMAND's). Without COMMAND it starts one, prints the URL and the
# command that stops it, and leaves it running (for working by hand).
#
# Debian's `postgresql` is installed when missing (as root, with apt-get). The cluster lives in a new
# temporary folder, listens on 127.0.0.1 only, on a free port, with a socket in that folder; it trusts
# local connections (nothing but this machine can reach it, and it holds only test data) and runs
# without fsync (a crash loses nothing worth keeping). It has a role `gaitscope` (may create
# databases) and an empty database `gaitscope_template`: the tests migrate it once and copy it for
# every test (`CREATE DATABASE ... TEMPLATE gaitscope_template`, tests/conftest.py).
set -euo pipefail

bindir() {
    local d
    for d in $(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V -r); do
        if [ -x "$d/initdb" ] && [ -x "$d/pg_ctl" ]; then echo "$d"; return 0; fi
    done
    return 1
}

if ! BIN=$(bindir); then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        echo "== installing Debian postgresql" >&2
        apt-get update -qq >/dev/null
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq postgresql >/dev/null
        BIN=$(bindir)
    else
        echo "postgres.sh: PostgreSQL is not installed and apt-get is unavailable (not root?)" >&2
        exit 1
    fi
fi

# initdb and postgres refuse to run as root: as root, the cluster belongs to the `postgres` user.
if [ "$(id -u)" = 0 ]; then
    id postgres >/dev/null 2>&1 || useradd --system --home-dir /var/lib/postgresql --shell /bin/bash postgres
    as_pg() { runuser -u postgres -- "$@"; }
else
    as_pg() { "$@"; }
fi

DIR=$(mktemp -d "${TMPDIR:-/tmp}/gaitscope-pg.XXXXXX")
chmod 755 "$DIR"
[ "$(id -u)" = 0 ] && chown postgres: "$DIR"
PORT=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
LOG="$DIR/server.log"

as_pg "$BIN/initdb" -D "$DIR/data" -U postgres --auth=trust -E UTF8 --locale=C.UTF-8 >/dev/null
as_pg "$BIN/pg_ctl" -D "$DIR/data" -l "$LOG" -w -t 60 start -o \
    "-h 127.0.0.1 -p $PORT -k $DIR -c fsync=off -c synchronous_commit=off -c full_page_writes=off -c max_connections=200" \
    >/dev/null

stop() {
    as_pg "$BIN/pg_ctl" -D "$DIR/data" -m fast -w stop >/dev/null 2>&1 || true
    rm -rf "$DIR"
}

psql_() { "$BIN/psql" -h 127.0.0.1 -p "$PORT" -U postgres -d postgres -v ON_ERROR_STOP=1 -q "$@"; }
if ! psql_ -c "CREATE ROLE gaitscope LOGIN CREATEDB" -c "CREATE DATABASE gaitscope_template OWNER gaitscope"; then
    cat "$LOG" >&2
    stop
    exit 1
fi

URL="postgresql+psycopg://gaitscope@127.0.0.1:$PORT/gaitscope_template"
if [ $# -eq 0 ]; then
    echo "GAITSCOPE_TEST_POSTGRES=$URL"
    echo "stop with: $( [ "$(id -u)" = 0 ] && echo 'runuser -u postgres -- ')$BIN/pg_ctl -D $DIR/data stop && rm -rf $DIR"
    exit 0
fi
trap stop EXIT
echo "== PostgreSQL $("$BIN/postgres" --version | awk '{print $3}') on 127.0.0.1:$PORT ($DIR)" >&2
status=0
GAITSCOPE_TEST_POSTGRES="$URL" "$@" || status=$?
exit "$status"
