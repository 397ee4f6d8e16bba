#!/usr/bin/env bash
# The test command: set-up, lint, type check, tests. Run from anywhere: `bash scripts/test.sh`.
# Installs Debian's chromium (browser tests) and nginx (scale-out tests) when missing and this user may use apt-get.
# Runs the tests on SQLite, then all but the browser (e2e) tests again on PostgreSQL (scripts/postgres.sh
# installs Debian's postgresql when it is missing, starts a throwaway server and stops it afterwards).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if ! command -v chromium >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        echo "== installing Debian chromium for the browser tests"
        apt-get update -qq >/dev/null
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
    else
        echo "== chromium missing and apt-get unavailable: browser tests will be skipped" >&2
    fi
fi
# nginx routes `serve --workers N`'s nodes (tests/server/test_cluster.py, test_proxy.py): Debian's, never started as a
# service here (the tests run it in the foreground on a configuration of their own).
if ! command -v nginx >/dev/null 2>&1 && [ ! -x /usr/sbin/nginx ]; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        echo "== installing Debian nginx for the scale-out tests"
        apt-get update -qq >/dev/null
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq nginx >/dev/null
    else
        echo "== nginx missing and apt-get unavailable: the scale-out tests will be skipped" >&2
    fi
fi
if ! command -v npm >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        echo "== installing Debian nodejs and npm for the browser code's checks"
        apt-get update -qq >/dev/null
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq nodejs npm >/dev/null
    else
        echo "== npm missing and apt-get unavailable: install Node.js (>= 18) for tsc and eslint" >&2
        exit 1
    fi
fi
echo "== ruff"
.venv/bin/ruff check .
echo "== mypy"
.venv/bin/mypy
# The browser code (web/*.js): TypeScript's type check of its JSDoc types (jsconfig.json) and ESLint's
# recommended rules (eslint.config.js), both from the locked package-lock.json.
echo "== tsc, eslint (web/)"
npm ci --no-audit --no-fund --loglevel=error
npx --no-install tsc --noEmit -p jsconfig.json
npx --no-install eslint web
echo "== pytest (SQLite)"
env -u GAITSCOPE_TEST_POSTGRES .venv/bin/python -m pytest -q "$@"
# The suite without the browser tests on a throwaway PostgreSQL server (each test gets its own database
# copied from a migrated template): the store and API tests cover PostgreSQL, and the e2e suite, which
# drives the same API through a browser, runs once (above). Exit status 5 is pytest's "every test
# deselected" (e.g. `bash scripts/test.sh tests/e2e`): nothing left to run there, not a failure. The
# estimators' tests and the offline studies' never open a database: they run once, above, too.
echo "== pytest (PostgreSQL, without e2e)"
bash scripts/postgres.sh .venv/bin/python -m pytest -q -m "not e2e" \
    --ignore=tests/estimators --ignore=tests/sessions/offline --ignore=tests/sessions/synth "$@" || [ $? = 5 ]
