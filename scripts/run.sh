#!/usr/bin/env bash
# Set up (or reuse) .venv and run sensorgym's main job on its built-in defaults.
# Extra arguments are passed to the `sensorgym` command instead of the default job.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/venv.sh"
if [ "$#" -eq 0 ]; then
    set -- demo
fi
exec "$VENV/bin/sensorgym" "$@"
