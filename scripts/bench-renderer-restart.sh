#!/usr/bin/env bash
# How long the fields run on extrapolation when the renderer process dies: flythrough on the wall
# clock with the renderer killed (SIGKILL, injected) four seconds in, RUNS times over the shipped
# Puget Sound map and once over the largest synthetic map (16384 x 16384 samples, ~2.8 GB).
# Writes docs/results/data/renderer_restart.json: per run, the recovery (kill noticed -> first new
# frame shown), the gap (last frame before -> first after), missed fields.
# Usage: scripts/bench-renderer-restart.sh [RUNS] [OUT_JSON]
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-5}"
out="${2:-docs/results/data/renderer_restart.json}"
fly=build/release/bin/flythrough
[ -x "$fly" ] || { echo "bench-renderer-restart: build first (cmake --build --preset release)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for i in $(seq 1 "$runs"); do
    "$fly" --duration 8 --out null --contact none --quiet --json "$tmp/puget-$i.json" \
        --inject-renderer-fault crash@4 >/dev/null 2>&1
done
"$fly" --synthetic 16384 --duration 8 --out null --contact none --quiet --json "$tmp/big-1.json" \
    --inject-renderer-fault crash@4 >/dev/null 2>&1
python3 - "$tmp" "$out" "$runs" <<'PY'
import glob, json, os, platform, sys
tmp, out, runs = sys.argv[1], sys.argv[2], sys.argv[3]
doc = {"what": "renderer process killed 4 s into an 8 s flythrough (wall clock, 720x486)",
       "cores": os.cpu_count(), "machine": platform.processor() or platform.machine(),
       "command": "scripts/bench-renderer-restart.sh " + runs, "maps": {}}
for name, label in (("puget", "Puget Sound 1025 x 1025"), ("big", "synthetic 16384 x 16384")):
    rows = []
    for path in sorted(glob.glob(f"{tmp}/{name}-*.json")):
        s = json.load(open(path))
        r = s["renderer_restarts"]
        rows.append({"missed_deadlines": s["missed_deadlines"], "restarts": len(r),
                     "recovery_ms": r[0]["recovery_ms"] if r else None,
                     "gap_ms": r[0]["gap_ms"] if r else None,
                     "render_fps": s["render_fps"]})
    doc["maps"][label] = rows
os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
json.dump(doc, open(out, "w"), indent=1)
for label, rows in doc["maps"].items():
    rec = sorted(x["recovery_ms"] for x in rows if x["recovery_ms"] is not None)
    print(f"{label}: recovery ms {rec}, missed {[x['missed_deadlines'] for x in rows]}")
PY
