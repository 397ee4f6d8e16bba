#!/usr/bin/env bash
# Runs docker/Dockerfile's steps outside a container (CI has no Docker daemon): builds the wheels, installs
# them into a fresh virtual environment as the image does, starts the server the image's way with the
# image's environment (on loopback, free ports, SQLite) and runs the image's HEALTHCHECK against it.
# The commands are generated from the Dockerfile on every run by docker/steps.py (what differs from the
# image, and why, is listed there).
#   bash docker/steps.sh            run them in a temporary folder, removed afterwards
#   bash docker/steps.sh --print    only show the generated script
#   KEEP=1 bash docker/steps.sh     keep the temporary folder (its server.log) for a look
# PYTHON: the CPython 3.11 standing in for the image's python (default python3).
set -euo pipefail
cd "$(dirname "$0")/.."
# The interpreter itself, not a launcher (a pyenv shim linked as `python` would pick another version).
PY=$("${PYTHON:-python3}" -c 'import sys; print(sys.executable)')
"$PY" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else "steps: needs Python 3.11 (the image'"'"'s), got " + sys.version)'
root=$(mktemp -d "${TMPDIR:-/tmp}/gaitscope-steps.XXXXXX")
if [ "${1:-}" = "--print" ]; then
    "$PY" docker/steps.py --root "$root" --python "$PY"
    rmdir "$root"
    exit 0
fi
if [ -z "${KEEP:-}" ]; then
    trap 'rm -rf "$root"' EXIT
else
    echo "steps: keeping $root"
fi
"$PY" docker/steps.py --root "$root" --python "$PY" --out "$root.sh"
mv "$root.sh" "$root/steps.generated.sh"
bash "$root/steps.generated.sh"
