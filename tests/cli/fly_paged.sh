#!/usr/bin/env bash
# flythrough over a terrain database larger than --cache-mb: the renderer pages each frame's
# tiles (ig/paged_terrain.hpp) on the field clock, in a thread and in its own process, and says
# what paging did; what it cannot fly over a paged map is refused, naming why.
set -u
bin=$1
tmp=$2/fly_paged
mkdir -p "$tmp"
fail() { echo "FAIL: $*" >&2; exit 1; }

"$bin/ig-build-db" --synthetic 1024:7 --tile 32 --out "$tmp/s.db" --quiet >/dev/null ||
    fail "build"
# 1800 m up (the map reaches 1635 m), looking down 20 degrees, turning 30 degrees a second.
printf 't,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,2000,2000,1800,45,-20,0\n1,2300,2300,1800,75,-20,10\n2,2600,2600,1800,105,-20,0\n' \
    >"$tmp/traj.csv"

for renderer in thread process; do
    rm -f "$tmp/fly.json"
    msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --trajectory "$tmp/traj.csv" \
        --renderer $renderer --clock simulated --out null --contact none \
        --json "$tmp/fly.json" 2>&1) || fail "fly ($renderer): $msg"
    python3 - "$tmp/fly.json" "$renderer" <<'PY' || fail "fly ($renderer): $msg"
import json, sys
j = json.load(open(sys.argv[1]))
p = j["paging"]
assert j["fields"] == 120, j["fields"]
assert j["missed_deadlines"] == 0, j["missed_deadlines"]
assert p["budget_mb"] == 6, p
assert not j["memory_locked"] and "paged" in j["memory_lock_error"], j["memory_lock_error"]
if sys.argv[2] == "thread":
    # Every frame paged, tiles read, the budget holds a frame: the first frame waits for its
    # tiles, and the misses end within the first second.
    assert p["frames"] == j["frames_rendered"], (p["frames"], j["frames_rendered"])
    assert p["tiles_read"] > 100, p
    assert p["frames_with_substitutions_after_1s"] == 0, p
    assert p["failed_tiles"] == 0, p
else:
    assert p["in_renderer_process"] and p["frames"] == 0, p
PY
done

# What a paged map cannot carry: a flight model's ground, the span caster.
msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --out null --contact none 2>&1)
[ $? -eq 2 ] || fail "no trajectory: not refused"
grep -q "s.db is over --cache-mb and is paged: a flight over it takes a --trajectory" <<<"$msg" ||
    fail "no trajectory: $msg"
msg=$("$bin/flythrough" --db "$tmp/s.db" --cache-mb 6 --trajectory "$tmp/traj.csv" \
    --caster span --out null --contact none 2>&1)
[ $? -eq 2 ] || fail "span: not refused"
grep -q "not --caster span" <<<"$msg" || fail "span: $msg"
echo ok
