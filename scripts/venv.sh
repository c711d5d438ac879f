# Sourced by run.sh and test.sh: create or reuse .venv and install sensorgym into it.
# torch is pinned to the CPU build that lies on this machine's disk; the project's own
# dependency stays a range (torch>=2.3), which the pinned build satisfies.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${SENSORGYM_VENV:-$ROOT/.venv}"
PYTHON="${PYTHON:-python3}"
if [ ! -x "$VENV/bin/python" ]; then
    "$PYTHON" -m venv "$VENV"
fi
echo "scripts/venv.sh: installing sensorgym and its dependencies into $VENV (minutes on a fresh machine)" >&2
"$VENV/bin/python" -m pip install --quiet --upgrade pip
"$VENV/bin/python" -m pip install --quiet "torch==2.13.0"
"$VENV/bin/python" -m pip install --quiet -e "$ROOT[test]"
# Compile every env's and rule's kernels into numba's disk cache, one process per env on all
# CPUs (cli/compile.py): paid once, and again only when the sources have changed; it prints
# a line per env package as it finishes (a progress bar on a terminal). A failure here is
# left for the job itself to report.
echo "scripts/venv.sh: compiling the kernels into numba's cache (once per change of the sources)" >&2
"$VENV/bin/sensorgym" compile --stamp "$VENV/.sensorgym-compiled" || echo "scripts/venv.sh: sensorgym compile failed" >&2
