#!/usr/bin/env bash
# Plots warp-eval's CSV (error against horizon per warp model) to a PNG with gnuplot.
# Usage: scripts/plot-warp-eval.sh WARP_EVAL.csv OUT.png [TITLE]
#   build/release/bin/warp-eval --csv warp_eval.csv && scripts/plot-warp-eval.sh warp_eval.csv plot.png
set -euo pipefail
if [ $# -lt 2 ] || [ $# -gt 3 ]; then
    echo "usage: $0 WARP_EVAL.csv OUT.png [TITLE]" >&2
    exit 2
fi
csv="$1" out="$2"
title="${3:-Warp error against horizon (all trajectories)}"
script="$(cd "$(dirname "$0")/.." && pwd)/sim/plots/warp_eval.gp"
command -v gnuplot >/dev/null || {
    echo "$0: gnuplot is not installed (Debian: apt-get install gnuplot-nox, or scripts/setup.sh)" >&2
    exit 3
}
[ -r "$csv" ] || { echo "$0: $csv: cannot read the CSV" >&2; exit 2; }
head -n 1 "$csv" | grep -q '^trajectory,model,horizon,psnr_db,mae_pct,ns_per_pixel' || {
    echo "$0: $csv: not a warp-eval CSV (expected the header trajectory,model,horizon,...)" >&2
    exit 2
}
grep -q '^all,' "$csv" || { echo "$0: $csv: no rows for trajectory 'all'" >&2; exit 2; }
# Single quotes inside gnuplot strings are doubled.
q() { printf "'%s'" "${1//\'/\'\'}"; }
tmp="$(dirname "$out")/.$(basename "$out").tmp$$.png"
trap 'rm -f "$tmp"' EXIT
gnuplot -e "csv=$(q "$csv"); out=$(q "$tmp"); title=$(q "$title")" "$script"
mv -f "$tmp" "$out"
trap - EXIT
