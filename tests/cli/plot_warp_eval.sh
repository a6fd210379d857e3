#!/usr/bin/env bash
# warp-eval's CSV plotted by scripts/plot-warp-eval.sh (gnuplot): a PNG of the expected size.
# Usage: plot_warp_eval.sh BIN_DIR REPO_DIR TMP_DIR. Exits 77 (skipped) when gnuplot is missing.
set -euo pipefail
bin="$1" repo="$2" tmp="$3"
command -v gnuplot >/dev/null || { echo "SKIP: gnuplot is not installed"; exit 77; }
csv="$tmp/plot_warp_eval.csv" png="$tmp/plot_warp_eval.png"
rm -f "$csv" "$png"
"$bin/warp-eval" --trajectory "$repo/data/trajectories/straight.csv" --size 96x64 --margin 16 \
    --frames 1 --horizons 1..3 --repeats 1 --csv "$csv" >/dev/null
"$repo/scripts/plot-warp-eval.sh" "$csv" "$png"
[ -s "$png" ] || { echo "FAIL: no plot written"; exit 1; }
# PNG signature, then the IHDR chunk: width and height, big-endian, at bytes 16..23.
sig=$(od -An -tx1 -N8 "$png" | tr -d ' \n')
[ "$sig" = "89504e470d0a1a0a" ] || { echo "FAIL: $png is not a PNG"; exit 1; }
read -r w h < <(od -An -tu4 --endian=big -j16 -N8 "$png")
echo "plot: ${w}x${h}"
[ "$w" -ge 400 ] && [ "$w" -le 4000 ] && [ "$h" -ge 300 ] && [ "$h" -le 4000 ] ||
    { echo "FAIL: plot is ${w}x${h}"; exit 1; }
# A file that is not warp-eval's CSV is refused with a message naming it.
if msg=$("$repo/scripts/plot-warp-eval.sh" "$repo/README.md" "$tmp/no.png" 2>&1); then
    echo "FAIL: a README was plotted"; exit 1
fi
grep -q "README.md" <<<"$msg" || { echo "FAIL: message does not name the input: $msg"; exit 1; }
[ ! -e "$tmp/no.png" ] || { echo "FAIL: a plot was left for a bad input"; exit 1; }
echo "PASS"
