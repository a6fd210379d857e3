#!/usr/bin/env bash
# Measures every figure of docs/results.md on this machine and regenerates the page:
# builds the release programs and benchmarks, runs them writing JSON into docs/results/data/,
# plots warp-eval's CSV (docs/warp_eval_prp.png) and the speed against error of the casters
# (docs/results/speed_error.png), then runs scripts/results.py.
# Takes about ten minutes on a 2-core machine (the synthetic 16384^2 map takes about 40 s to
# generate the first time; a raw copy is kept in $VIG_BENCH_CACHE, default /tmp/vig-bench-cache).
#
# Usage: scripts/results.sh [--skip-build] [--only NAME...]
#   NAME: machine caster render detail appearance insets warp warp-eval stereo flythrough io restart cigi objects  (default: all)
#   field-clock (twenty minutes: scripts/bench-field-clock.sh 600) runs only when named.
set -euo pipefail
cd "$(dirname "$0")/.."
root="$PWD"
bin="$root/build/release/bin"
data="$root/docs/results/data"
cache="${VIG_BENCH_CACHE:-/tmp/vig-bench-cache}"
build=1
only=()
while [ $# -gt 0 ]; do
    case "$1" in
        --skip-build) build=0 ;;
        --only)
            shift
            case "${1:-}" in
                machine|caster|render|detail|appearance|insets|warp|warp-eval|stereo|flythrough|io|restart|cigi|objects|field-clock) only+=("$1") ;;
                *) echo "$0: --only ${1:-}: expected machine, caster, render, detail, appearance, insets, warp, warp-eval, stereo, flythrough, io, restart, cigi, objects or field-clock" >&2
                   exit 2 ;;
            esac ;;
        *) echo "usage: $0 [--skip-build] [--only NAME]..." >&2; exit 2 ;;
    esac
    shift
done
wanted() {
    [ ${#only[@]} -eq 0 ] && return 0
    local n
    for n in "${only[@]}"; do [ "$n" = "$1" ] && return 0; done
    return 1
}

if [ "$build" = 1 ]; then
    scripts/setup.sh
    cmake --preset release >/dev/null
    cmake --build --preset release -j "$(nproc)" --target bench-caster bench-render bench-warp bench-objects bench-truth ig-render \
        warp-eval stereo-eval flythrough io-check
fi
mkdir -p "$data" "$cache"
commands="$data/commands.tsv"
touch "$commands"
start=$(date +%s)

# run NAME COMMAND...: runs a program from build/release/bin, its output to the terminal, and
# records the command (as a user types it from the repository root) and the load average when
# it started (the machine may be shared) for the page.
run() {
    local name="$1"
    shift
    local shown="$*"
    shown="${shown//$bin\//build/release/bin/}"
    shown="${shown//$data\//docs/results/data/}"
    shown="${shown//$cache/\/tmp\/cache}"
    echo "== $name: $shown" >&2
    local t0=$SECONDS load
    load=$(cut -d' ' -f1 /proc/loadavg)
    "$@"
    grep -v "^$name	" "$commands" >"$commands.new" || true
    printf '%s\t%s\t%s\n' "$name" "$load" "$shown" >>"$commands.new"
    sort "$commands.new" >"$commands"
    rm -f "$commands.new"
    echo "== $name: $((SECONDS - t0)) s" >&2
}

if wanted machine; then
    # The machine, once for the page.
    python3 - "$data/machine.json" <<'EOF'
import json, os, platform, subprocess, sys, datetime
cpu = "unknown"
flags = set()
for line in open("/proc/cpuinfo"):
    if line.startswith("model name") and cpu == "unknown":
        cpu = line.split(":", 1)[1].strip()
    if line.startswith("flags") and not flags:
        flags = set(line.split(":", 1)[1].split())
mem = 0
for line in open("/proc/meminfo"):
    if line.startswith("MemTotal"):
        mem = int(line.split()[1]) * 1024
def out(*a):
    try:
        return subprocess.run(a, capture_output=True, text=True).stdout.strip().splitlines()[0]
    except Exception:
        return "unknown"
simd = "AVX-512" if {"avx512f", "avx512bw", "avx512dq", "avx512vl"} <= flags else (
    "AVX2" if "avx2" in flags else "no AVX2")
json.dump({"cpu": cpu, "cores": os.cpu_count(), "memory_gib": round(mem / 2**30),
           "simd": simd, "os": out("sh", "-c", ". /etc/os-release && echo $PRETTY_NAME"),
           "compiler": out("c++", "--version"),
           "load_average_at_start": os.getloadavg()[0],
           "revision": out("git", "rev-parse", "--short", "HEAD"),
           "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d")},
          open(sys.argv[1], "w"), indent=1)
EOF
fi

if wanted caster; then
    # Repetitions of the benchmarks interleaved, so a change in the machine's load weighs on all.
    run caster_bench "$bin/bench-caster" --benchmark_repetitions=3 \
        --benchmark_enable_random_interleaving=true \
        --benchmark_out="$data/caster_bench.json" --benchmark_out_format=json
fi

if wanted render; then
    # One process: the 16384^2 map is generated (or loaded from the cache) once.
    run render_bench "$bin/bench-render" speed packets sensitivity threads headings pitches \
        quality flight stream --size 16384 --repeat 3 --cache "$cache" \
        --json "$data/render_bench.json"
    scripts/plot-speed-error.sh "$data/render_bench.json" docs/results/speed_error.png
    # The span caster against a Comanche-style peer and the multiresolution caster, per view.
    run span_bench "$bin/bench-render" span span-threads --size 16384 --repeat 3 --cache "$cache" \
        --json "$data/span_bench.json"
fi

if wanted detail; then
    # Lower detail, what a paged flight draws over its placing budget: time and error per step.
    run render_detail "$bin/bench-render" detail --size 4096 --repeat 3 --cache "$cache" \
        --json "$data/render_detail.json"
fi

if wanted appearance; then
    run render_autosample "$bin/bench-render" autosample --size 4096 --image 720x486 --repeat 3 \
        --cache "$cache" --json "$data/render_autosample.json"
    run render_batch scripts/bench-batch.sh build/release/bin "$data/render_batch.json" 24 3
    run render_lighting "$bin/bench-render" lighting --size 4096 --repeat 3 --cache "$cache" \
        --json "$data/render_lighting.json"
    run render_edge_fill "$bin/bench-render" edge-fill --json "$data/render_edge_fill.json"
fi

if wanted insets; then
    for image in 720x486 1920x1080; do
        run render_insets_$image "$bin/bench-render" insets --image $image --repeat 5 \
            --json "$data/render_insets_$image.json"
    done
fi

if wanted warp; then
    run warp_bench "$bin/bench-warp" --benchmark_repetitions=8 --benchmark_min_time=0.2 \
        --benchmark_enable_random_interleaving=true \
        --benchmark_out="$data/warp_bench.json" --benchmark_out_format=json
    # The whole processor on a field of a frame with depth: the depth warp against the quadratic.
    run depth_warp_bench "$bin/bench-warp" \
        --benchmark_filter='BM_Prp[DP][eo][pl]' \
        --benchmark_repetitions=10 --benchmark_enable_random_interleaving=true \
        --benchmark_out="$data/depth_warp_bench.json" --benchmark_out_format=json
fi

if wanted warp-eval; then
    run warp_eval "$bin/warp-eval" --json "$data/warp_eval.json" --csv "$data/warp_eval.csv"
    # The depth model's gather (Newton steps from the quadratic, the splat where they do not settle).
    run warp_eval_gather "$bin/warp-eval" --depth-warp gather --models poly,depth,auto \
        --json "$data/warp_eval_gather.json"
    scripts/plot-warp-eval.sh "$data/warp_eval.csv" docs/warp_eval_prp.png \
        "Warp error against horizon, 320x240, 5 trajectories"
    # Frames and truths by the exact single level instead of the multiresolution caster.
    run warp_eval_levels0 "$bin/warp-eval" --levels 0 --json "$data/warp_eval_levels0.json"
    # Moving targets: a vehicle's centroid in warped fields against true renders.
    run target_eval "$bin/target-eval" --frames 24 --json "$data/target_eval.json"
fi

if wanted stereo; then
    goleta=(--height data/goleta-512/sba_elev32_wgs84_512x512.tif
            --color data/goleta-512/sba_rgb_wgs84_512x512.tif)
    run stereo_puget_720x486 "$bin/stereo-eval" --size 720x486 --sweep 12 --repeat 3 \
        --json "$data/stereo_puget_720x486.json"
    run stereo_puget_1920x1080 "$bin/stereo-eval" --size 1920x1080 --sweep 12 --repeat 3 \
        --json "$data/stereo_puget_1920x1080.json"
    run stereo_goleta_720x486 "$bin/stereo-eval" "${goleta[@]}" --size 720x486 --sweep 12 \
        --repeat 3 --json "$data/stereo_goleta_720x486.json"
    run stereo_goleta_1920x1080 "$bin/stereo-eval" "${goleta[@]}" --size 1920x1080 --sweep 12 \
        --repeat 3 --json "$data/stereo_goleta_1920x1080.json"
    run stereo_goleta_500x400 "$bin/stereo-eval" "${goleta[@]}" --size 500x400 --sweep 12 \
        --repeat 3 --json "$data/stereo_goleta_500x400.json"
    # Five times the eye separation.
    run stereo_puget_720x486_agl0.1 "$bin/stereo-eval" --size 720x486 --sweep 12 --repeat 3 \
        --stereo-agl 0.1 --json "$data/stereo_puget_720x486_agl0.1.json"
    run stereo_goleta_720x486_agl0.1 "$bin/stereo-eval" "${goleta[@]}" --size 720x486 --sweep 12 \
        --repeat 3 --stereo-agl 0.1 --json "$data/stereo_goleta_720x486_agl0.1.json"
fi

if wanted flythrough; then
    # Stereo (2 m between the eyes, 720x486 per eye, side by side) against mono, both with the
    # renderer as a thread of the field process, so the two rates compare.
    run flythrough_stereo "$bin/flythrough" --stereo 2 --renderer thread --duration 60 --out null \
        --contact none --quiet --json "$data/flythrough_stereo.json"
    # The pair's render rate against mono: short runs in turn, so the machine's drift falls on
    # both alike (one long run of each differed by more than the pair's cost).
    for i in 1 2 3; do
        run "flythrough_rate_stereo_$i" "$bin/flythrough" --stereo 2 --renderer thread \
            --duration 15 --out null --contact none --quiet \
            --json "$data/flythrough_rate_stereo_$i.json"
        run "flythrough_rate_mono_$i" "$bin/flythrough" --renderer thread --duration 15 \
            --out null --contact none --quiet --json "$data/flythrough_rate_mono_$i.json"
    done
    # The default scenario over Puget Sound, unthrottled renderer, on the wall clock: three runs
    # with the default multiresolution caster, two with the exact single level.
    for i in 1 2 3; do
        run "flythrough_auto_$i" "$bin/flythrough" --duration 20 --out null --contact none --quiet \
            --json "$data/flythrough_auto_$i.json"
    done
    for i in 1 2; do
        run "flythrough_levels0_$i" "$bin/flythrough" --levels 0 --duration 20 --out null \
            --contact none --quiet --json "$data/flythrough_levels0_$i.json"
    done
    # Every render modelled as taking 1/12 s: reproducible to the field.
    run flythrough_simulated "$bin/flythrough" --clock simulated --duration 10 --out null \
        --contact none --quiet --json "$data/flythrough_simulated.json"
fi

if wanted io; then
    run io_check "$bin/io-check" pattern --out null --duration 20 --json "$data/io_check.json"
    run io_check_realtime "$bin/io-check" pattern --out null --duration 60 --realtime \
        --json "$data/io_check_realtime.json"
    run io_check_y4m "$bin/io-check" pattern --out y4m:/tmp/pattern.y4m \
        --duration 10 --json "$data/io_check_y4m.json"
    rm -f /tmp/pattern.y4m
fi

# The renderer process: restarts (about 2.5 minutes, most of it making the 16384^2 map), and the
# field clock over ten minutes against the renderer thread (only when named: twenty minutes).
if wanted restart; then
    scripts/bench-renderer-restart.sh 5 "$data/renderer_restart.json"
fi
# CIGI over loopback: host message to field, with and without a flood; decoding rates (a minute).
if wanted cigi; then
    scripts/bench-cigi.sh 20 "$data/cigi_bench.json"
fi
# Voxel objects: a populated Puget Sound against the same view without, error against the
# reference, memory per object (about a minute).
if wanted objects; then
    run objects_bench "$bin/bench-objects" --repeat 3 --json "$data/objects_bench.json"
    run truth_bench "$bin/bench-truth" --repeat 3 --json "$data/truth_bench.json"
    # Ground truth on the wall clock at 720x486: the demo scene's low pass over the forest.
    run flythrough_truth "$bin/flythrough" --scene data/scenes/puget-sound.json \
        --start 52250,37950,+120,40 --out null --contact none --quiet --truth /tmp/truth.jsonl \
        --json "$data/flythrough_truth.json"
    rm -f /tmp/truth.jsonl
fi
if [ ${#only[@]} -gt 0 ] && wanted field-clock; then
    scripts/bench-field-clock.sh 600 "$data/field_clock.json"
fi

# Paths inside the data are written relative to the repository.
sed -i "s#$root/##g" "$data"/*.json "$data"/*.csv 2>/dev/null || true
echo "results.sh: measured in $(($(date +%s) - start)) s" >&2
python3 scripts/results.py
