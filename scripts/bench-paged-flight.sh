#!/usr/bin/env bash
# A real-time flight over a terrain database far larger than the memory it may use, for
# docs/results.md: a synthetic map built into a database (ig-build-db), a trajectory that turns
# one full field of view (60 degrees) a second for a third of the run and then flies at 300 m/s
# low over the terrain, flown by flythrough on the wall clock with the renderer paging the
# database through --cache-mb (peak RSS, missed fields, tiles drawn from a coarser level,
# tiles read a second), REPEATS times per image size, each in turn with the same flight over a
# 4096^2 map loaded whole (the missed fields this machine gives without paging); and the cost
# of paging itself: a shorter flight over the 4096^2 database paged and loaded whole, three
# times each in turn, render time per frame side by side. The renderer is flythrough's default,
# a process of its own (its paging figures reach the report through sim::PagingLog). Writes
# docs/results/data/paged_flight_SIZE.json.
# Usage: scripts/bench-paged-flight.sh [BUILD_DIR] [SCRATCH_DIR] [SIZE] [CACHE_MB] [SECONDS]
#                                      [IMAGES] [FULL_DETAIL_IMAGES] [REPEATS]
#   defaults: build/release, /tmp/vig-paged-flight, 16384, 512, 60, "720x486", "", 1
#   (65536 needs ~45 GB free and half an hour to build on a 2-core machine; IMAGES is a list of
#   WxH, e.g. "720x486 1920x1080", flown with flythrough's default placing budget (frames over
#   it drawn at lower detail); FULL_DETAIL_IMAGES are flown again, once, with
#   --place-budget-ms 0. The 4096^2 comparison, paged against in memory, is flown at full
#   detail.)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
scratch=${2:-/tmp/vig-paged-flight}
size=${3:-16384}
cacheMb=${4:-512}
seconds=${5:-60}
images=${6:-720x486}
fullImages=${7:-}
repeats=${8:-1}
data=$root/docs/results/data
bin=$build/bin
mkdir -p "$scratch" "$data"

db() {  # db SIZE: the synthetic map SIZE:1 in tiles of 64, built once
    local out="$scratch/synthetic_$1.db"
    [ -s "$out" ] || "$bin/ig-build-db" --synthetic "$1:1" --out "$out" --quiet \
        --json "$scratch/build_$1.json" >&2
    echo "$out"
}

# trajectory DB OUT SECONDS: the flight over DB's map, its heights read from the database's
# level-0 tiles (docs/formats.md): a third of the run turning 60 degrees a second at 100 m/s,
# 250 m above the highest ground near the circle, looking 15 degrees down; the rest at 300 m/s,
# 60 m above the highest ground within 200 m of the track, looking 6 degrees down, after a
# descent over the first 4 s of it (48 m/s down: the two heights and pitches blended).
trajectory() {
    python3 - "$1" "$2" "$3" "$root/scripts" <<'PY'
import math, sys
sys.path.insert(0, sys.argv[4])
from terrain_db_samples import LevelZero
path, out, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
db = LevelZero(path)
w, hh, sx, sy = db.width, db.height, db.sx, db.sy
height = db.nearest
def highest(x, y, r):
    return max(height(x + a * r / 2, y + b * r / 2) for a in range(-2, 3) for b in range(-2, 3))
ext_x, ext_y = (w - 1) * sx, (hh - 1) * sy
x, y, yaw = 0.3 * ext_x, 0.3 * ext_y, 45.0
turn = seconds / 3
rows = ["t,x,y,z,yaw_deg,pitch_deg,roll_deg"]
t, dt = 0.0, 0.25
while t <= seconds + 1e-9:
    if t <= turn:
        z = highest(x, y, 250.0) + 250.0
        rows.append(f"{t:.3f},{x:.2f},{y:.2f},{z:.2f},{yaw:.3f},-15,0")
        speed, rate = 100.0, 60.0
    else:
        blend = min(1.0, (t - turn) / 4.0)
        z = highest(x, y, 200.0) + 250.0 + (60.0 - 250.0) * blend
        pitch = -15.0 + (-6.0 + 15.0) * blend
        weave = 10.0 * math.sin(2 * math.pi * (t - turn) / 20.0)
        rows.append(f"{t:.3f},{x:.2f},{y:.2f},{z:.2f},{yaw + weave:.3f},{pitch:.3f},0")
        speed, rate = 300.0, 0.0
    x += speed * dt * math.sin(math.radians(yaw))
    y += speed * dt * math.cos(math.radians(yaw))
    yaw = (yaw + rate * dt) % 360.0
    t += dt
open(out, "w").write("\n".join(rows) + "\n")
PY
}

# fly NAME DB CACHE_MB SECONDS TRAJECTORY WxH PLACE_BUDGET_MS: one wall-clock flight with the
# default renderer (its own process), its JSON kept
fly() {
    local dropped=0
    sync
    if echo 3 >/proc/sys/vm/drop_caches 2>/dev/null; then dropped=1; fi
    # Let the machine settle: on the 2-core virtual machine the results were measured on, a
    # 1920x1080 flight started right after a paged one missed 20 fields in 15 s (stalls of
    # ~30 ms at each new frame, in memory as well as paged) and none 15 s later.
    sleep "${VIG_SETTLE_S:-15}"
    "$bin/flythrough" --db "$2" --cache-mb "$3" --trajectory "$5" --duration "$4" \
        --size "$6" --place-budget-ms "$7" --colors image --out null \
        --contact none --quiet --json "$scratch/$1.json" >&2
    python3 - "$scratch/$1.json" "$dropped" "$7" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
j["page_cache_dropped"] = sys.argv[2] == "1"
j["place_budget_ms"] = float(sys.argv[3])
json.dump(j, open(sys.argv[1], "w"), indent=2)
PY
}

big=$(db "$size")
small=$(db 4096)
trajectory "$big" "$scratch/flight_$size.csv" "$seconds"
trajectory "$small" "$scratch/flight_4096_long.csv" "$seconds"
for rep in $(seq 1 "$repeats"); do  # in turn with the same flight in memory
    for image in $images; do
        fly "paged_${size}_${image}_$rep" "$big" "$cacheMb" "$seconds" \
            "$scratch/flight_$size.csv" "$image" 60
        fly "whole_4096_${image}_$rep" "$small" 4096 "$seconds" "$scratch/flight_4096_long.csv" \
            "$image" 60
    done
done
for image in $fullImages; do
    fly "paged_${size}_${image}_full" "$big" "$cacheMb" "$seconds" "$scratch/flight_$size.csv" \
        "$image" 0
done

short=$((seconds < 15 ? seconds : 15))
trajectory "$small" "$scratch/flight_4096.csv" "$short"
for rep in 1 2 3; do  # in turn, so the machine's drift falls on both alike
    fly "paged_4096_$rep" "$small" 64 "$short" "$scratch/flight_4096.csv" 720x486 0
    fly "whole_4096_$rep" "$small" 4096 "$short" "$scratch/flight_4096.csv" 720x486 0
done

python3 - "$data/paged_flight_$size.json" "$scratch" "$size" "$cacheMb" "$seconds" "$images" \
    "$fullImages" "$repeats" <<'PY'
import json, os, sys
out, scratch, size, cache_mb, seconds, images, full, repeats = sys.argv[1:9]
reps = range(1, int(repeats) + 1)
def load(name):
    return json.load(open(os.path.join(scratch, name + ".json")))
build = os.path.join(scratch, f"build_{size}.json")
doc = {
    "command": f"scripts/bench-paged-flight.sh build/release /tmp/vig-paged-flight {size} "
               f"{cache_mb} {seconds} '{images}' '{full}' {repeats}",
    "load_average": os.getloadavg()[0], "cpus": os.cpu_count(),
    "size": int(size), "cache_mb": float(cache_mb), "seconds": float(seconds),
    "db_bytes": os.path.getsize(os.path.join(scratch, f"synthetic_{size}.db")),
    "build": json.load(open(build)) if os.path.exists(build) else None,
    "renderer": "process",
    "flights": [load(f"paged_{size}_{image}_{r}") for r in reps for image in images.split()],
    "whole_flights": [load(f"whole_4096_{image}_{r}") for r in reps for image in images.split()],
    "flights_full_detail": [load(f"paged_{size}_{image}_full") for image in full.split()],
    "paged_4096": [load(f"paged_4096_{r}") for r in (1, 2, 3)],
    "whole_4096": [load(f"whole_4096_{r}") for r in (1, 2, 3)]}
json.dump(doc, open(out, "w"), indent=2)
PY
echo "wrote $data/paged_flight_$size.json"
