#!/usr/bin/env bash
# flythrough over a terrain database larger than --cache-mb: the renderer pages each frame's
# tiles (ig/paged_terrain.hpp) on the field clock, in a thread and in its own process, and says
# what paging did; the default scenario flies over it on the flight model's own ground; what it
# cannot fly over a paged map is refused, naming why.
set -u
bin=$1
tmp=$2/fly_paged
root=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$tmp"
fail() { echo "FAIL: $*" >&2; exit 1; }

"$bin/ig-build-db" --synthetic 1024:7 --tile 32 --out "$tmp/s.db" --quiet >/dev/null ||
    fail "build"
# 1800 m up (the map reaches 1635 m), looking down 20 degrees, turning 30 degrees a second.
printf 't,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,2000,2000,1800,45,-20,0\n1,2300,2300,1800,75,-20,10\n2,2600,2600,1800,105,-20,0\n' \
    >"$tmp/traj.csv"

# Full detail throughout (--place-budget-ms 0): which tiles a frame needs does not depend on
# how fast this machine writes them.
for renderer in thread process; do
    rm -f "$tmp/fly.json"
    msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --trajectory "$tmp/traj.csv" \
        --renderer $renderer --clock simulated --out null --contact none --place-budget-ms 0 \
        --json "$tmp/fly.json" 2>&1) || fail "fly ($renderer): $msg"
    python3 - "$tmp/fly.json" "$renderer" <<'PY' || fail "fly ($renderer): $msg"
import json, sys
j = json.load(open(sys.argv[1]))
p = j["paging"]
assert j["fields"] == 120, j["fields"]
assert j["missed_deadlines"] == 0, j["missed_deadlines"]
assert p["budget_mb"] == 6, p
assert not j["memory_locked"] and "paged" in j["memory_lock_error"], j["memory_lock_error"]
# Tiles read, none unreadable, every frame's paging logged. A renderer process's figures reach
# the field process (sim::PagingLog), with its own resident memory on top of the field
# process's; a renderer process restarted on a loaded machine may have logged a frame it never
# delivered.
assert p["tiles_read"] > 100, p
assert p["failed_tiles"] == 0, p
assert p["frames_reduced_detail"] == 0 and p["detail_min"] == 1.0, p
assert p["frames_not_kept"] == 0, p
# The renderer's fullest frame and what it held: the cache within its budget; its silences.
full = p["renderer_fullest_frame"]
assert full["rss_mb"] > 0 and 0 < full["tile_cache_mb"] <= 6, full
assert full["map_pages_held_mb"] > 0, full
assert 0 <= p["renderer_silence_ms_p99"] <= p["renderer_silence_ms_max"], p
if sys.argv[2] == "thread":
    # The budget holds a frame: the first frame waits for its tiles, and the misses end within
    # the first second.
    assert p["frames"] == j["frames_rendered"], (p["frames"], j["frames_rendered"])
    assert p["frames_with_substitutions_after_1s"] == 0, p
    assert not p["in_renderer_process"], p
    assert p["peak_rss_mb"] == p["field_process_peak_rss_mb"], p
    assert p["renderer_process_peak_rss_mb"] == 0, p
else:
    assert p["frames"] >= j["frames_rendered"] > 0, (p["frames"], j["frames_rendered"])
    assert p["in_renderer_process"], p
    assert p["renderer_process_peak_rss_mb"] > 0, p
    assert p["peak_rss_mb"] == p["field_process_peak_rss_mb"] + p["renderer_process_peak_rss_mb"], p
PY
done

# --prefetch-s takes effect: prefetching 3 s ahead along the motion reads more tiles than the
# frame's own footprint (0 s), and --tile-loaders is taken or refused.
for ahead in 0 3; do
    msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --trajectory "$tmp/traj.csv" \
        --renderer thread --clock simulated --prefetch-s $ahead --tile-loaders 3 --out null \
        --contact none --json "$tmp/ahead_$ahead.json" 2>&1) || fail "--prefetch-s $ahead: $msg"
done
python3 - "$tmp/ahead_0.json" "$tmp/ahead_3.json" <<'PY' || fail "--prefetch-s"
import json, sys
near = json.load(open(sys.argv[1]))["paging"]["tiles_read"]
far = json.load(open(sys.argv[2]))["paging"]["tiles_read"]
assert far > 1.2 * near, (near, far)
print("tiles read prefetching 0 s ahead: %d, 3 s ahead: %d" % (near, far))
PY
msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --trajectory "$tmp/traj.csv" \
    --tile-loaders 0 --out null --contact none 2>&1)
[ $? -eq 2 ] || fail "--tile-loaders 0: not refused"
grep -q -- "--tile-loaders 0" <<<"$msg" || fail "--tile-loaders 0: $msg"

# --place-budget-ms: a budget no frame's writes fit draws the frames after the first at lower
# detail, down to --min-detail and not below; the fields go on. Bad values are refused.
rm -f "$tmp/detail.json"
msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --trajectory "$tmp/traj.csv" \
    --renderer thread --clock simulated --place-budget-ms 0.000001 --min-detail 0.6 \
    --out null --contact none --json "$tmp/detail.json" 2>&1) || fail "--place-budget-ms: $msg"
grep -q "frames at lower detail (down to 0.71)" <<<"$msg" || fail "--place-budget-ms: $msg"
python3 - "$tmp/detail.json" <<'PY' || fail "--place-budget-ms"
import json, sys
j = json.load(open(sys.argv[1]))
p = j["paging"]
assert j["fields"] == 120 and j["missed_deadlines"] == 0, (j["fields"], j["missed_deadlines"])
# 0.6 lies between two steps of 2^(-1/4): the lowest is the one above it, 2^(-1/2).
assert abs(p["detail_min"] - 2 ** -0.5) < 1e-9, p
assert p["frames_reduced_detail"] >= p["frames"] - 2, p
PY
for bad in "--place-budget-ms -1" "--min-detail 0.1" "--min-detail nan"; do
    msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --trajectory "$tmp/traj.csv" \
        $bad --out null --contact none 2>&1)
    [ $? -eq 2 ] || fail "$bad: not refused"
    grep -q -- "${bad% *}" <<<"$msg" || fail "$bad: $msg"
done

# The default scenario over the paged map, started 20 m over the ground: the flight model stands
# on a ground of its own (ig/paged_ground.hpp), exact where its tiles are resident; the field log's
# poses stay over the terrain (the database's samples, read here from its level-0 tiles).
rm -f "$tmp/stick.json" "$tmp/fields.jsonl"
msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --start 2000,2000,+20,45 --duration 2 \
    --clock simulated --out null --contact none --json "$tmp/stick.json" \
    --field-log "$tmp/fields.jsonl" 2>&1) || fail "default scenario over a paged map: $msg"
grep -q "the flight model's ground" <<<"$msg" || fail "default scenario: no ground line: $msg"
python3 - "$tmp/stick.json" "$tmp/fields.jsonl" "$tmp/s.db" "$root/scripts" <<'PY' ||
import json, sys
sys.path.insert(0, sys.argv[4])
from terrain_db_samples import LevelZero
j = json.load(open(sys.argv[1]))
assert j["fields"] == 120 and j["missed_deadlines"] == 0, (j["fields"], j["missed_deadlines"])
g = j["paging"]["ground"]
assert g["exact"] > 0 and g["tiles_read"] > 0, g
assert g["exact"] >= 10 * (g["bounded"] + g["outside"]), g
surface = LevelZero(sys.argv[3]).surface  # the map's bilinear surface
n, lowest = 0, 1e300
for line in open(sys.argv[2]):
    p = json.loads(line)["pose"]
    clearance = p["z"] - surface(p["x"], p["y"])
    assert clearance > 0.0, (p, clearance)
    lowest = min(lowest, clearance)
    n += 1
assert lowest < 100.0, lowest  # the flight came down near its floor
assert n == 120, n
PY
    fail "default scenario: $msg"
# A scene over the paged map: its placements stand on the database's ground (read at load), the
# moving tank on the renderer's own ground; the objects are drawn (the video differs from the
# same flight without them) and no field is missed.
cat >"$tmp/scene.json" <<JSON
{"models": {"house": {"vox": "$root/data/models/house.vox"}, "tank": {"vox": "$root/data/models/tank.vox"}},
 "objects": [{"id": 1, "model": "tank", "trajectory": "$tmp/tank.csv", "scale": 3}],
 "scatter": [{"model": "house", "count": 400, "area": [2400, 2400, 3600, 3600], "seed": 5,
              "scale": 8, "first_id": 100}]}
JSON
printf 't,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,2600,2600,0,45,0,0\n10,3000,3000,0,45,0,0\n' >"$tmp/tank.csv"
for with in scene none; do
    extra=()
    [ $with = scene ] && extra=(--scene "$tmp/scene.json")
    msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --trajectory "$tmp/traj.csv" \
        --clock simulated --size 160x120 --margin 8 --render-threads 1 \
        --out "y4m:$tmp/$with.y4m" --contact none --json "$tmp/fly_$with.json" "${extra[@]}" \
        2>&1) || fail "scene over a paged map ($with): $msg"
done
python3 - "$tmp/fly_scene.json" "$tmp/scene.y4m" "$tmp/none.y4m" <<'PY' ||
import json, sys
j = json.load(open(sys.argv[1]))
assert j["fields"] == 120 and j["missed_deadlines"] == 0, (j["fields"], j["missed_deadlines"])
a = open(sys.argv[2], "rb").read()
b = open(sys.argv[3], "rb").read()
assert len(a) == len(b) and len(a) > 0, (len(a), len(b))
differ = sum(1 for x, y in zip(a, b) if x != y)
assert differ > 10000, differ  # the objects are drawn
print("bytes differing with the scene: %d" % differ)
PY
    fail "scene over a paged map: $msg"
# The truth over the paged map and over the same map in memory (the database was built from
# --synthetic 1024:7): where each object truly is, field by field, is the same.
for where in paged memory; do
    terrain=(--db "$tmp/s.db" --cache-mb 6)
    [ $where = memory ] && terrain=(--synthetic 1024:7)
    msg=$("$bin/flythrough" "${terrain[@]}" --trajectory "$tmp/traj.csv" \
        --scene "$tmp/scene.json" --truth "$tmp/truth_$where.jsonl" --clock simulated \
        --size 160x120 --margin 8 --render-threads 1 --out null --contact none 2>&1) ||
        fail "truth ($where): $msg"
done
python3 - "$tmp/truth_paged.jsonl" "$tmp/truth_memory.jsonl" <<'PY' || fail "truth over a paged map"
import json, sys
a = [json.loads(l) for l in open(sys.argv[1])]
b = [json.loads(l) for l in open(sys.argv[2])]
assert len(a) == len(b) == 120, (len(a), len(b))
pairs = 0
for x, y in zip(a, b):
    ox = {o["id"]: o for o in x["objects"]}
    oy = {o["id"]: o for o in y["objects"]}
    for i in set(ox) & set(oy):
        assert ox[i]["true_bbox"] == oy[i]["true_bbox"], (x["field"], ox[i], oy[i])
        assert ox[i]["range_m"] == oy[i]["range_m"], (x["field"], ox[i], oy[i])
        pairs += 1
assert pairs > 2000, pairs
print("truth: %d objects placed the same over the paged map and in memory" % pairs)
PY

# Stereo pairs over the paged map (both eyes' tiles placed; PagedRenderer.StereoPairs* compares
# them with the in-memory pairs): side by side, every field on time; with a scene, refused.
msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --trajectory "$tmp/traj.csv" \
    --stereo 0.5 --renderer thread --clock simulated --size 160x120 --margin 8 \
    --render-threads 1 --out "y4m:$tmp/stereo.y4m" --contact none --json "$tmp/stereo.json" \
    2>&1) || fail "stereo over a paged map: $msg"
head -c 40 "$tmp/stereo.y4m" | grep -q "W320 H120" || fail "stereo: not side by side"
python3 - "$tmp/stereo.json" <<'PY' || fail "stereo over a paged map: $msg"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["fields"] == 120 and j["missed_deadlines"] == 0, (j["fields"], j["missed_deadlines"])
assert j["stereo"]["separation_m"] == 0.5, j["stereo"]
assert j["paging"]["frames"] == j["frames_rendered"] and j["paging"]["tiles_read"] > 0, j["paging"]
PY
# With a scene: the objects drawn over both eyes after the terrain's reprojection, in a thread
# and in a renderer process; the pairs differ from the bare ones in both halves.
for renderer in thread process; do
    msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --trajectory "$tmp/traj.csv" \
        --stereo 0.5 --scene "$tmp/scene.json" --renderer $renderer --clock simulated \
        --size 160x120 --margin 8 --render-threads 1 --out "y4m:$tmp/stereo_scene.y4m" \
        --contact none --json "$tmp/stereo_scene.json" 2>&1) ||
        fail "stereo with a scene over a paged map ($renderer): $msg"
    python3 - "$tmp/stereo_scene.json" "$tmp/stereo.y4m" "$tmp/stereo_scene.y4m" <<'PY' ||
import json, sys
j = json.load(open(sys.argv[1]))
assert j["fields"] == 120 and j["missed_deadlines"] == 0, (j["fields"], j["missed_deadlines"])
assert j["scene"]["static_objects"] + j["scene"]["moving_objects"] > 0, j["scene"]
def frames(path):
    data = open(path, "rb").read()
    header, _, rest = data.partition(b"\n")
    w = int(next(f[1:] for f in header.split() if f.startswith(b"W")))
    h = int(next(f[1:] for f in header.split() if f.startswith(b"H")))
    out, pos = [], 0
    while pos < len(rest):
        pos = rest.index(b"\n", pos) + 1
        out.append(rest[pos:pos + w * h])
        pos += w * h * 2  # 4:2:2
    return w, h, out
w, h, bare = frames(sys.argv[2])
_, _, drawn = frames(sys.argv[3])
halves = [0, 0]
for a, b in zip(bare, drawn):
    for y in range(h):
        row = slice(y * w, (y + 1) * w)
        ra, rb = a[row], b[row]
        halves[0] += ra[: w // 2] != rb[: w // 2]
        halves[1] += ra[w // 2 :] != rb[w // 2 :]
assert halves[0] > 0 and halves[1] > 0, halves
PY
        fail "stereo with a scene over a paged map ($renderer): $msg"
done

# A CIGI host over the paged map: its HAT/HOT requests and lines of sight are answered on a
# thread of their own from the database's samples (sim/terrain_queries.hpp), a field or more
# later, while the fields go on; the heights equal the database's surface (read here from its
# level-0 tiles). The renderer in a thread: in a process, its first frame (which waits for its
# tiles) can outlast the process's first-frame allowance under the sanitizers.
rm -f "$tmp/port" "$tmp/host.json" "$tmp/cigi.json"
"$bin/cigi-host" --port-file "$tmp/port" --seconds 4 --queries 4 --origin 47,-122,0 \
    --start 2000,2000,1900 --speed 100 --pitch 0 --json "$tmp/host.json" 2>"$tmp/host.err" &
hpid=$!
for i in $(seq 1 300); do [ -s "$tmp/port" ] && break; sleep 0.1; done
[ -s "$tmp/port" ] || fail "cigi-host wrote no port"
msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --renderer thread --cigi 127.0.0.1:0 \
    --cigi-host "127.0.0.1:$(cat "$tmp/port")" --cigi-origin 47,-122 --cigi-wait 10 \
    --duration 3 --size 160x120 --margin 8 --render-threads 1 --out null --contact none \
    --json "$tmp/cigi.json" 2>&1) || fail "cigi over a paged map: $msg"
wait "$hpid" || fail "cigi-host: $(cat "$tmp/host.err")"
grep -q "cigi: over the paged map" <<<"$msg" || fail "cigi: no queries line: $msg"
python3 - "$tmp/cigi.json" "$tmp/host.json" "$tmp/s.db" "$root/scripts" <<'PY' ||
import json, sys
sys.path.insert(0, sys.argv[4])
from terrain_db_samples import LevelZero
j = json.load(open(sys.argv[1]))
h = json.load(open(sys.argv[2]))["queries"]
c = j["cigi"]
q = j["paging"]["host_queries"]
assert j["fields"] == 180 and j["missed_deadlines"] == 0, (j["fields"], j["missed_deadlines"])
# Every answer waited for the thread, none unknown; tiles were read for them.
assert c["deferred_answers"] == c["answers"] and c["answers"] >= 300, c
assert c["unknown_terrain_answers"] == 0 and q["unknown"] == 0 and q["refused"] == 0, (c, q)
assert q["tiles_read"] > 0, q
# What the host received: HAT/HOT and lines of sight, every one valid.
assert h["hat_hot_answers"] >= 240 and h["los_answers"] >= 60, h
assert h["valid"] == h["hat_hot_answers"] + h["los_answers"], h
# Late by the thread's placing, not lost: bounds far above what a quiet machine measures (at
# most 1 field; 8 host frames from sending, the run's start included), loose enough for the
# sanitizer builds (3 fields, 18 host frames measured under AddressSanitizer).
assert c["max_answer_fields"] <= 30, c
assert h["max_host_frames"] <= 90, h
surface = LevelZero(sys.argv[3]).surface
worst = max(abs(hot - surface(x, y)) for x, y, hot in h["hot_samples"])
assert len(h["hot_samples"]) >= 200 and worst < 1e-3, (len(h["hot_samples"]), worst)
print("worst HOT error %.3g m over %d answers" % (worst, len(h["hot_samples"])))
PY
    fail "cigi over a paged map: $msg"
msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --trajectory "$tmp/traj.csv" \
    --caster span --out null --contact none 2>&1)
[ $? -eq 2 ] || fail "span: not refused"
grep -q "not --caster span" <<<"$msg" || fail "span: $msg"
echo ok
