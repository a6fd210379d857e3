#!/usr/bin/env bash
# Plots speed against error (bench-render's quality section: frame time and colour error against
# a supersampled reference, per caster and rays per pixel) to a PNG with gnuplot.
# Usage: scripts/plot-speed-error.sh RENDER_BENCH.json OUT.png
#   build/release/bin/bench-render quality --json q.json && scripts/plot-speed-error.sh q.json q.png
set -euo pipefail
if [ $# -ne 2 ]; then
    echo "usage: $0 RENDER_BENCH.json OUT.png" >&2
    exit 2
fi
json="$1" out="$2"
script="$(cd "$(dirname "$0")/.." && pwd)/sim/plots/speed_error.gp"
command -v gnuplot >/dev/null || {
    echo "$0: gnuplot is not installed (Debian: apt-get install gnuplot-nox, or scripts/setup.sh)" >&2
    exit 3
}
csv="$(mktemp)"
tmp="$(dirname "$out")/.$(basename "$out").tmp$$.png"
trap 'rm -f "$csv" "$tmp"' EXIT
# The CSV gnuplot reads, and the plot's title.
title="$(python3 - "$json" "$csv" <<'PY'
import json, sys
try:
    q = json.load(open(sys.argv[1]))["quality"]
except (OSError, ValueError, KeyError) as e:
    sys.exit(f"{sys.argv[1]}: no bench-render quality section ({e})")
with open(sys.argv[2], "w") as f:
    f.write("levels,rays,ms,mae_pct\n")
    for r in q["rows"]:
        f.write(f"{r['levels']},{r['supersample']},{r['ms']:.3f},{r['mae_pct_vs_reference']:.5f}\n")
print(f"Speed against error, {q['image']} over {q['map']}, pitch {q['pitch_deg']:.0f} deg")
PY
)"
gnuplot -e "csv='$csv'; out='${tmp//\'/\'\'}'; title='$title'" "$script"
mv -f "$tmp" "$out"
