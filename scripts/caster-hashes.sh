#!/usr/bin/env bash
# Hashes every image the casters make (caster-hashes: pose sweeps on Puget Sound, Goleta and a
# synthetic map; every caster, level setting, supersampling, kernel, node skipping; stereo pairs)
# and compares them with a recorded list.
#   scripts/caster-hashes.sh [BUILD_DIR] [RECORDED]   (default: build/release,
#                                                       docs/design/data/caster_hashes_before.txt)
# Prints the number of images and of those that differ; exits 1 when any differs.
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build/release}"
recorded="${2:-docs/design/data/caster_hashes_before.txt}"
now="$(mktemp)"
trap 'rm -f "$now"' EXIT
"$build/bin/caster-hashes" --poses 16 >"$now"
total=$(wc -l <"$now")
differ=$(diff "$recorded" "$now" | grep -c '^>' || true)
echo "caster-hashes: $total images, $differ differ from $recorded"
[ "$differ" -eq 0 ] && [ "$total" -eq "$(wc -l <"$recorded")" ]
