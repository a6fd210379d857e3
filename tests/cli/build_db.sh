#!/usr/bin/env bash
# ig-build-db end to end: the same input gives the same bytes; an interrupted build (killed
# outright, or stopped by a signal) leaves no database that opens; the result verifies.
# Usage: build_db.sh BIN_DIR TMP_DIR
set -u
bin="$1"; tmp="$2/build_db"
rm -rf "$tmp"; mkdir -p "$tmp"
fail() { echo "FAIL: $*"; exit 1; }

"$bin/ig-build-db" --synthetic 256:5 --tile 32 --out "$tmp/a.db" --quiet >/dev/null || fail "build a"
"$bin/ig-build-db" --synthetic 256:5 --tile 32 --out "$tmp/b.db" --quiet >/dev/null || fail "build b"
cmp -s "$tmp/a.db" "$tmp/b.db" || fail "two builds of the same input differ"
"$bin/ig-db-info" --verify "$tmp/a.db" | grep -q '"verified_tiles"' || fail "verify"
[ -e "$tmp/a.db.partial" ] && fail "partial file left after a finished build"

# The database as a map for every program (--db): the same frame as the map it was built from;
# a map over --cache-mb is rendered paged by the reference, naive and fast casters (the same
# image as the whole map's, the fast one at every level setting), refused with the span caster
# and by programs that load the map whole.
if [ -x "$bin/ig-render" ]; then
    "$bin/ig-render" --synthetic 256:5 --pose 800,600,+300,40,-20,0 --size 64x48 \
        --out "$tmp/syn.png" >/dev/null || fail "render --synthetic"
    "$bin/ig-render" --db "$tmp/a.db" --pose 800,600,+300,40,-20,0 --size 64x48 \
        --out "$tmp/db.png" >/dev/null || fail "render --db"
    cmp -s "$tmp/syn.png" "$tmp/db.png" || fail "--db renders another frame than the map"
    for caster in reference naive fast:auto fast:0 fast:2; do
        c=${caster%%:*}
        levels=()
        [ "$c" = fast ] && levels=(--levels "${caster#*:}")
        "$bin/ig-render" --db "$tmp/a.db" --caster $c "${levels[@]}" \
            --pose 800,600,+300,40,-20,0 --size 64x48 --out "$tmp/whole_$caster.png" \
            >/dev/null 2>&1 || fail "render $caster"
        "$bin/ig-render" --db "$tmp/a.db" --cache-mb 0.4 --caster $c "${levels[@]}" \
            --pose 800,600,+300,40,-20,0 --size 64x48 --out "$tmp/paged_$caster.png" \
            --json "$tmp/paged_$caster.json" >/dev/null 2>&1 || fail "render $caster paged"
        cmp -s "$tmp/whole_$caster.png" "$tmp/paged_$caster.png" ||
            fail "--db paged ($caster) renders another frame than the whole map"
        grep -q '"tiles_substituted": 0' "$tmp/paged_$caster.json" ||
            fail "paged ($caster): tiles substituted"
    done
    # A scene over the paged map: its objects stand on the database's ground (read tile by tile
    # as the scene asks), so the frame and its object ids are those of the whole map's.
    root=$(cd "$(dirname "$0")/../.." && pwd)
    printf 't,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,1000,900,0,30,0,0\n10,1300,1200,0,30,0,0\n' \
        >"$tmp/tank.csv"
    cat >"$tmp/scene.json" <<JSON
{"models": {"house": {"vox": "$root/data/models/house.vox"}, "tank": {"vox": "$root/data/models/tank.vox"}},
 "objects": [{"id": 1, "model": "tank", "trajectory": "$tmp/tank.csv", "scale": 2}],
 "scatter": [{"model": "house", "count": 150, "area": [900, 700, 1800, 1600], "seed": 2,
              "scale": 2, "first_id": 100}]}
JSON
    for c in reference fast; do
        for where in whole paged; do
            budget=()
            [ $where = paged ] && budget=(--cache-mb 0.4)
            "$bin/ig-render" --db "$tmp/a.db" "${budget[@]}" --caster $c --scene "$tmp/scene.json" \
                --time 2 --pose 800,600,+300,40,-20,0 --size 96x72 --out "$tmp/s_${where}_$c.png" \
                --objects-out "$tmp/id_${where}_$c.png" --json "$tmp/s_${where}_$c.json" \
                >/dev/null 2>&1 || fail "render a scene ($where, $c)"
        done
        cmp -s "$tmp/s_whole_$c.png" "$tmp/s_paged_$c.png" ||
            fail "a scene over the paged map ($c): another frame than over the whole map"
        cmp -s "$tmp/id_whole_$c.png" "$tmp/id_paged_$c.png" ||
            fail "a scene over the paged map ($c): other object ids than over the whole map"
        python3 - "$tmp/s_paged_$c.json" <<'PY' || fail "a scene over the paged map ($c): no objects"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["paging"]["tiles_substituted"] == 0, j["paging"]
assert sum(o["pixels"] for o in j["objects"]) > 200, j["objects"]
PY
    done
    # A stereo pair over the paged map (both eyes' tiles placed): the whole map's pair, with the
    # right eye reprojected and cast whole.
    for right in reproject raycast; do
        for where in whole paged; do
            budget=()
            [ $where = paged ] && budget=(--cache-mb 0.4)
            "$bin/ig-render" --db "$tmp/a.db" "${budget[@]}" --stereo 40 --right $right \
                --pose 800,600,+300,40,-20,0 --size 96x72 --out-left "$tmp/l_${where}_$right.png" \
                --out-right "$tmp/r_${where}_$right.png" >/dev/null 2>&1 ||
                fail "render a stereo pair ($where, $right)"
        done
        cmp -s "$tmp/l_whole_$right.png" "$tmp/l_paged_$right.png" &&
            cmp -s "$tmp/r_whole_$right.png" "$tmp/r_paged_$right.png" ||
            fail "a stereo pair over the paged map ($right): another pair than the whole map's"
    done
    # A budget below the frame's tiles: drawn from a coarser level, and said.
    msg=$("$bin/ig-render" --db "$tmp/a.db" --cache-mb 0.1 --caster reference \
        --pose 800,600,+300,40,-20,0 --size 64x48 --out "$tmp/coarse.png" 2>&1) ||
        fail "render paged below the frame's tiles: $msg"
    grep -q "of the frame's .* tiles did not fit --cache-mb 0.1: drawn from a coarser level" \
        <<<"$msg" || fail "paged below the frame's tiles: $msg"
    msg=$("$bin/ig-render" --db "$tmp/a.db" --cache-mb 0.1 --caster span --size 64x48 \
        --out "$tmp/x.png" 2>&1)
    rc=$?
    [ "$rc" -eq 2 ] || fail "--cache-mb below the map, span caster: exit $rc"
    grep -q -- "--caster span: .*a.db is over --cache-mb and is rendered paged" <<<"$msg" ||
        fail "--cache-mb below the map, span caster: $msg"
    [ -e "$tmp/x.png" ] && fail "--cache-mb below the map: an image was written"
    msg=$("$bin/ig-render" --db "$tmp/a.db" --synthetic 64 --size 64x48 --out "$tmp/x.png" 2>&1)
    grep -q -- "--db: the database holds the map" <<<"$msg" || fail "--db with --synthetic: $msg"
fi

# Killed outright part-way: nothing at the output path; the partial file does not open.
for sig in KILL TERM; do
    out="$tmp/killed_$sig.db"
    "$bin/ig-build-db" --synthetic 4096:2 --tile 64 --out "$out" --quiet >/dev/null 2>&1 &
    pid=$!
    for _ in $(seq 1 400); do
        [ -s "$out.partial" ] && [ "$(stat -c %s "$out.partial")" -gt 300000 ] && break
        sleep 0.05
    done
    kill -s "$sig" "$pid" 2>/dev/null || fail "build finished before it could be interrupted"
    wait "$pid" 2>/dev/null
    [ -e "$out" ] && fail "SIG$sig: a database was left at $out"
    if [ "$sig" = TERM ] && [ -e "$out.partial" ]; then fail "SIGTERM left $out.partial"; fi
    if [ -e "$out.partial" ]; then
        msg=$("$bin/ig-db-info" "$out.partial" 2>&1); rc=$?
        [ "$rc" -eq 2 ] || fail "partial file: ig-db-info exit $rc"
        grep -q "not a terrain database" <<<"$msg" || fail "partial file: $msg"
    fi
done
echo ok
