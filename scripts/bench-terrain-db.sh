#!/usr/bin/env bash
# Terrain database measurements for docs/results.md: tile size and codec (bench-tiles: file
# size, level-0 tile read rate cold and warm, frame footprint bytes), and the streaming
# builder's throughput and peak memory on large synthetic maps (ig-build-db).
# Usage: scripts/bench-terrain-db.sh [BUILD_DIR] [SCRATCH_DIR] [SIZES...]
#   defaults: build/release, /tmp/vig-terrain-db, sizes 16384 32768 (65536 needs ~45 GB free)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}; shift || true
scratch=${1:-/tmp/vig-terrain-db}; shift || true
sizes=("$@"); [ ${#sizes[@]} -eq 0 ] && sizes=(16384 32768)
data=$root/docs/results/data
mkdir -p "$scratch"

"$build/bin/bench-tiles" --size 4096 --runs 5 --dir "$scratch" --json "$data/terrain_db_tiles.json"

runs=()
for size in "${sizes[@]}"; do
    out="$scratch/synthetic_$size.db"
    "$build/bin/ig-build-db" --synthetic "$size:1" --tile 256 --out "$out" --quiet \
        --json "$scratch/build_$size.json"
    runs+=("$scratch/build_$size.json")
    rm -f "$out"
done
python3 - "$data/terrain_db_build.json" "${runs[@]}" <<'PY'
import json, os, sys
out, files = sys.argv[1], sys.argv[2:]
runs = [json.load(open(f)) for f in files]
doc = {"command": "ig-build-db --synthetic SIZE:1 --tile 256 --out DB",
       "load_average": os.getloadavg()[0], "cpus": os.cpu_count(), "runs": runs}
json.dump(doc, open(out, "w"), indent=2)
PY
echo "wrote $data/terrain_db_tiles.json $data/terrain_db_build.json"
