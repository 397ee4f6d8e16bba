#!/usr/bin/env bash
# The test command: set-up, lint, type check, tests. Run from anywhere: `bash scripts/test.sh`.
# Installs Debian's chromium for the browser tests when it is missing and this user may use apt-get.
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
echo "== ruff"
.venv/bin/ruff check .
echo "== mypy"
.venv/bin/mypy
echo "== pytest"
.venv/bin/python -m pytest -q "$@"
