#!/usr/bin/env bash
# Set up (or reuse) .venv, install the docs extra if it is missing, and build the docs site:
# Sphinx over docs/ (MyST pages, an env page generated from each registered env's docstring,
# the API reference) into docs/_build/html/ (open docs/_build/html/index.html). Warnings are
# errors. .ci/run calls this after the tests. Extra arguments go to sphinx-build.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/venv.sh"
cd "$ROOT"
if ! "$VENV/bin/python" -c "import sphinx, furo, myst_parser" 2>/dev/null; then
    echo "scripts/docs.sh: installing the docs extra (sphinx, furo, myst-parser) into $VENV" >&2
    "$VENV/bin/python" -m pip install --quiet -e "$ROOT[test,docs]"
fi
exec "$VENV/bin/sphinx-build" -W --keep-going -b html docs docs/_build/html "$@"
