#!/usr/bin/env bash
# Set up, build and run the main job on its built-in default: a flythrough over the shipped
# Puget Sound terrain, written to out/ (a Y4M video and a contact sheet PNG). Without arguments
# it flies the default stick script low over the shipped scene's forest and village (voxel
# objects, a tank on the village road); with arguments, they go to flythrough as they are.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cmake --preset release >/dev/null
cmake --build --preset release -j "$(nproc)"
if [ "$#" -eq 0 ]; then
    set -- --scene data/scenes/puget-sound.json --start 52250,37950,+120,40
fi
exec build/release/bin/flythrough "$@"
