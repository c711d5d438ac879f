#!/usr/bin/env bash
# Set up (or reuse) .venv and run the test suite. Extra arguments go to pytest.
# The tests run in one pytest-xdist worker per CPU (each worker keeps to one thread:
# tests/conftest.py); `bash scripts/test.sh -n 0 ...` runs them in this one process.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/venv.sh"
cd "$ROOT"
exec "$VENV/bin/python" -m pytest -q -n auto --dist worksteal "$@"
