#!/usr/bin/env bash
# Creates .venv and installs gaitscope with its dev tools. Idempotent; safe to run again.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    "$PY" -m venv .venv
fi
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e ".[dev]"
# The opensourceleg SDK, for sessions/devices/osl.py and its tests, without its dependencies: it pins numpy<2
# (and pandas<3), which would downgrade ours; the parts used (its abstract bases, offline mode) are pure Python
# and run on numpy 2, as tests/sessions/devices/test_osl.py checks. Not in pyproject's dependencies for that pin.
.venv/bin/python -m pip install --quiet --no-deps "opensourceleg==3.5.0"
# mypy reads the packages as gaitscope.* through links (it does not follow the editable install's import hook)
mkdir -p .typecheck/gaitscope
for d in estimators server sessions; do ln -sfn "../../$d" ".typecheck/gaitscope/$d"; done
# compile the numba kernels now (about a minute), not in the first server's or replay's first seconds
.venv/bin/gaitscope warm
