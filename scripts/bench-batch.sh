#!/usr/bin/env bash
# Batch rendering throughput: ig-render --poses over N poses of the shipped map at 720x486 (one
# process, the terrain loaded once) against one ig-render process per frame, REPEAT times each
# (interleaved), wall clock. Writes JSON (frames, per-run seconds of each way) to OUT.
# Usage: scripts/bench-batch.sh BIN_DIR OUT [FRAMES] [REPEAT]
set -euo pipefail
bin="$1"; out="$2"; frames="${3:-24}"; repeat="${4:-3}"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
poses="$tmp/poses.txt"
for ((k = 0; k < frames; k++)); do
    echo "$((40000 + 500 * k)),$((30000 + 400 * k)),+$((300 + 40 * k)),$((20 + 7 * k)),-$((4 + k % 20)),0"
done > "$poses"
batch=(); single=()
for ((r = 0; r < repeat; r++)); do
    t0=$EPOCHREALTIME
    "$bin/ig-render" --poses "$poses" --size 720x486 --out "$tmp/b_####.png" 2>/dev/null
    t1=$EPOCHREALTIME
    k=0
    while read -r pose; do
        "$bin/ig-render" --pose "$pose" --size 720x486 --out "$tmp/s_$k.png" 2>/dev/null
        k=$((k + 1))
    done < "$poses"
    t2=$EPOCHREALTIME
    batch+=("$t0:$t1"); single+=("$t1:$t2")
done
python3 - "$out" "$frames" "${batch[*]}" "${single[*]}" "$(nproc)" <<'PY'
import json, sys
out, frames, batch, single, cores = sys.argv[1:]
def span(pair):
    a, b = pair.split(":")
    return float(b) - float(a)
json.dump({"frames": int(frames), "image": "720x486", "map": "Puget Sound 1k (shipped)",
           "cores": int(cores), "batch_s": [span(x) for x in batch.split()],
           "single_s": [span(x) for x in single.split()]}, open(out, "w"), indent=1)
print(f"bench-batch: {frames} frames: batch {[round(span(x), 2) for x in batch.split()]} s, "
      f"one process per frame {[round(span(x), 2) for x in single.split()]} s", file=sys.stderr)
PY
