#!/usr/bin/env bash
# Set up, build and run the main job on its built-in default: a flythrough over the shipped
# Puget Sound terrain, written to out/ (a Y4M video and a contact sheet PNG).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cmake --preset release >/dev/null
cmake --build --preset release -j "$(nproc)"
exec build/release/bin/flythrough "$@"
