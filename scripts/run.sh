#!/usr/bin/env bash
# Set up (or reuse) .venv and run sensorgym's main job on its built-in defaults.
# Extra arguments are passed to the `sensorgym` command instead of the main job
# (`sensorgym benchmark`, cli/main.py DEFAULT_JOB; bare `sensorgym` only prints its help).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/venv.sh"
if [ "$#" -eq 0 ]; then
    set -- benchmark
fi
exec "$VENV/bin/sensorgym" "$@"
