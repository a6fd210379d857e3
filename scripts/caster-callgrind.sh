#!/usr/bin/env bash
# Instructions per pixel of the fast caster under callgrind: the issue camera (1920x1080, heading
# 45, pitch -10, 300 m up at 20 km, 20 km) over the synthetic 16384^2 map, levels auto and 0, one
# frame, counting only ig::renderFrame (the map's loading and the caster's set-up excluded).
# Valgrind has no AVX-512, so the caster runs the kernel the processor it emulates has (recorded).
#   scripts/caster-callgrind.sh [BENCH_RENDER] [REVISION] [JSON]
#     BENCH_RENDER  default build/release/bin/bench-render
#     REVISION      label of the runs ("before" | "after"; default after)
#     JSON          default docs/results/data/caster_callgrind.json; its other runs are kept,
#                   those of this revision, level setting and kernel replaced
#   CALLGRIND_RUNS  the runs as LEVELS[:KERNEL] words (default "auto 0": the default kernel;
#                   a kernel needs a bench-render with --kernel)
set -euo pipefail
cd "$(dirname "$0")/.."
bench="${1:-build/release/bin/bench-render}"
revision="${2:-after}"
json="${3:-docs/results/data/caster_callgrind.json}"
size="${CALLGRIND_MAP_SIZE:-16384}"
cache="${CALLGRIND_CACHE:-/tmp/vig-callgrind-cache}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mkdir -p "$cache"
# A first run without valgrind writes the map's raw copy (fast to load under valgrind).
"$bench" frame --size "$size" --image 64x48 --cache "$cache" --repeat 1 >/dev/null
for run in ${CALLGRIND_RUNS:-auto 0}; do
    levels="${run%%:*}"
    kernelArgs=()
    [ "$run" != "$levels" ] && kernelArgs=(--kernel "${run#*:}")
    valgrind --tool=callgrind --callgrind-out-file="$work/cg.$run" --collect-atstart=no \
        --toggle-collect='ig::renderFrame*' \
        "$bench" frame --size "$size" --image 1920x1080 --cache "$cache" --caster fast \
        --levels "$levels" "${kernelArgs[@]}" --repeat 1 >"$work/out.$run" 2>"$work/err.$run"
    instructions=$(grep -E '^(summary|totals):' "$work/cg.$run" | head -1 | awk '{print $2}')
    kernel=$(sed -n 's/.*kernel \([a-z0-9-]*\).*/\1/p' "$work/out.$run" | head -1)
    echo "levels $levels: $instructions instructions, kernel ${kernel:-?}"
    echo "$levels $instructions ${kernel:-avx2}" >>"$work/runs"
done
python3 - "$json" "$revision" "$size" "$work/runs" <<'PY'
import json, os, platform, sys
path, revision, size, runs = sys.argv[1:5]
doc = {"machine": "", "camera": "1920x1080", "map": f"synthetic {size}", "runs": []}
if os.path.exists(path):
    doc = json.load(open(path))
cpu = ""
try:
    for line in open("/proc/cpuinfo"):
        if line.startswith("model name"):
            cpu = line.split(":", 1)[1].strip()
            break
except OSError:
    pass
doc["machine"] = f"{cpu or platform.processor()}, valgrind callgrind (no AVX-512)"
pixels = 1920 * 1080
for line in open(runs):
    levels, n, kernel = line.split()
    doc["runs"] = [r for r in doc["runs"]
                   if (r.get("revision"), r.get("levels"), r.get("kernel")) != (revision, levels, kernel)]
    doc["runs"].append({"levels": levels, "kernel": kernel, "revision": revision,
                        "instructions": int(n), "pixels": pixels,
                        "instructions_per_pixel": round(int(n) / pixels, 1)})
json.dump(doc, open(path, "w"), indent=2)
open(path, "a").write("\n")
PY
