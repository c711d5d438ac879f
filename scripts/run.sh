#!/usr/bin/env bash
# Set up (or reuse) .venv and run sensorgym's main job on its built-in defaults.
# Extra arguments are passed to the `sensorgym` command instead of the default job
# (without arguments `sensorgym` runs its main job, cli/main.py DEFAULT_JOB).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/venv.sh"
exec "$VENV/bin/sensorgym" "$@"
