#!/usr/bin/env bash
# Set up (or reuse) .venv, then run the tests that compare with numbers recorded on another
# machine (pytest marker `arithmetic`: golden episodes and reproduction reports, shipped
# policies' scores, the book's bounds) once under each other arithmetic path below, as
# another x86-64 CPU or BLAS build would compute them. .ci/run calls this after the suite.
# Extra arguments go to pytest.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/venv.sh"
cd "$ROOT"
run() {
    echo "== arithmetic path: $*"
    env "$@" "$VENV/bin/python" -m pytest -q -n auto --dist worksteal -m arithmetic "${EXTRA[@]}"
}
EXTRA=("$@")
# torch's matmuls through MKL: SSE4.2 code instead of the CPU's widest, and MKL's
# conditional-numerical-reproducibility mode (another summation order)
run MKL_ENABLE_INSTRUCTIONS=SSE4_2
run MKL_CBWR=COMPATIBLE
# a CPU without AVX2 and FMA, as far as we can make one: numba's kernels compiled for a generic
# x86-64 (in a cache of their own), glibc's libm variants without FMA, torch's own kernels
# without vector extensions
run NUMBA_CPU_NAME=generic NUMBA_CACHE_DIR="$VENV/numba-cache-generic" \
    GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA ATEN_CPU_CAPABILITY=default
