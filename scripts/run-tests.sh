#!/usr/bin/env bash
# Set up, build and run the whole test suite. Usage: scripts/run-tests.sh [PRESET] (default release).
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
scripts/setup.sh
werror=OFF
[ "${CI:-}" = "true" ] && werror=ON
cmake --preset "$preset" -DVIG_WERROR="$werror" >/dev/null
cmake --build --preset "$preset" -j "$(nproc)"
ctest --preset "$preset"
