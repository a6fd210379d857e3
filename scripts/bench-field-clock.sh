#!/usr/bin/env bash
# The field clock under load: flythrough on the wall clock for SECONDS (default 600) at 720x486,
# the renderer process unthrottled on every core, killed with SIGKILL once halfway; then the
# same run with the renderer as a thread of the field process (all cores but one, no kill).
# Writes docs/results/data/field_clock.json: each run's stats, the resident memory of the field
# process at one minute and at the end, and the renderer's kill-to-first-frame recovery.
# Usage: scripts/bench-field-clock.sh [SECONDS] [OUT_JSON]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-600}"
out="${2:-docs/results/data/field_clock.json}"
fly=build/release/bin/flythrough
[ -x "$fly" ] || { echo "bench-field-clock: build first (cmake --build --preset release)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

rss_kb() { awk '/^VmRSS/ {print $2}' "/proc/$1/status" 2>/dev/null || echo 0; }

run() {  # run NAME KILL_AT_SECONDS FLAGS...
    local name="$1" kill_at="$2"; shift 2
    "$fly" --duration "$seconds" --out null --contact none --quiet --json "$tmp/$name.json" "$@" \
        >/dev/null 2>"$tmp/$name.err" &
    local pid=$! start; start=$(date +%s)
    local rss1=0 killed=0
    while kill -0 "$pid" 2>/dev/null; do
        local now=$(( $(date +%s) - start ))
        [ "$rss1" -eq 0 ] && [ "$now" -ge 60 ] && rss1=$(rss_kb "$pid")
        if [ "$kill_at" -gt 0 ] && [ "$killed" -eq 0 ] && [ "$now" -ge "$kill_at" ]; then
            local child; child=$(pgrep -P "$pid" | head -n 1 || true)
            [ -n "$child" ] && kill -9 "$child" && killed=1
        fi
        rssEnd=$(rss_kb "$pid"); [ "$rssEnd" -gt 0 ] && last_rss=$rssEnd
        sleep 1
    done
    wait "$pid"
    python3 - "$tmp/$name.json" "$name" "$rss1" "${last_rss:-0}" "$killed" >"$tmp/$name.run" <<'PY'
import json, sys
stats = json.load(open(sys.argv[1]))
print(json.dumps({"name": sys.argv[2], "rss_kb_at_60s": int(sys.argv[3]),
                  "rss_kb_at_end": int(sys.argv[4]), "renderer_killed": sys.argv[5] == "1",
                  "stats": stats}))
PY
}

run process "$((seconds / 2))" --renderer process
run thread 0 --renderer thread
python3 - "$tmp/process.run" "$tmp/thread.run" "$seconds" "$out" <<'PY'
import json, os, platform, sys
runs = [json.loads(open(p).read()) for p in sys.argv[1:3]]
doc = {"what": "flythrough wall clock, 720x486 uyvy, default scenario",
       "seconds": float(sys.argv[3]), "cores": os.cpu_count(), "machine": platform.processor() or platform.machine(),
       "command": "scripts/bench-field-clock.sh " + sys.argv[3], "runs": runs}
os.makedirs(os.path.dirname(sys.argv[4]) or ".", exist_ok=True)
json.dump(doc, open(sys.argv[4], "w"), indent=1)
for r in runs:
    s = r["stats"]
    print(f"{r['name']:8} missed {s['missed_deadlines']}  jitter p99 {s['field_jitter_ms']['p99']:.3f} "
          f"p99.9 {s['field_jitter_ms']['p99.9']:.3f} max {s['field_jitter_ms']['max']:.3f} ms  "
          f"render {s['render_fps']:.1f} fps  rss {r['rss_kb_at_60s']} -> {r['rss_kb_at_end']} kB  "
          f"restarts {[(x['cause'], x['recovery_ms']) for x in s['renderer_restarts']]}")
PY
