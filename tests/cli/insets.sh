#!/usr/bin/env bash
# High-resolution insets from the command line (docs/design/insets.md): ig-render draws one
# nested in a synthetic map and one read from a raster placed on a global sample; flythrough
# flies over them on the field clock; what cannot take insets is refused, naming why.
# Usage: insets.sh BIN_DIR TMP_DIR
set -u
bin=$1
tmp=$2/insets
rm -rf "$tmp"; mkdir -p "$tmp"
fail() { echo "FAIL: $*" >&2; exit 1; }

pose=3600,3000,+300,20,-25,0
common=(--synthetic 1024:3 --spacing 8 --pose $pose --size 160x100 --levels auto)
"$bin/ig-render" "${common[@]}" --inset synthetic:400,400,128,128,4 --out "$tmp/nested.png" \
    --json "$tmp/nested.json" 2>/dev/null || fail "render with a synthetic inset"
"$bin/ig-render" "${common[@]}" --colors image --out "$tmp/plain.png" 2>/dev/null ||
    fail "render without"
cmp -s "$tmp/nested.png" "$tmp/plain.png" && fail "the inset changed nothing"
python3 - "$tmp/nested.json" <<'PY' || fail "json"
import json, sys
j = json.load(open(sys.argv[1]))
(i,) = j["insets"]
assert i["cells"] == [400, 400, 528, 528] and i["factor"] == 4 and i["spacing_m"] == 2.0, i
PY

# A raster inset placed by hand: a 16-bit PNG of 33 x 33 heights (metres, a 40 m dome) on
# global sample (410, 410), four times finer: drawn (seen from above), named in the JSON.
python3 - "$tmp/dome.png" <<'PY' || fail "write the PNG"
import math, struct, sys, zlib
n = 33
rows = b""
for r in range(n):
    row = b"\x00"
    for c in range(n):
        d = math.hypot(c - 16, r - 16) / 16.0
        row += struct.pack(">H", int(60 + 40 * max(0.0, 1.0 - d * d)))
    rows += row
def chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", n, n, 16, 0, 0, 0, 0))
png += chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
open(sys.argv[1], "wb").write(png)
PY
down=(--synthetic 1024:3 --spacing 8 --pose 3312,2950,+300,0,-60,0 --size 160x100)
"$bin/ig-render" "${down[@]}" --inset "$tmp/dome.png@410,410,4" --out "$tmp/dome_view.png" \
    --json "$tmp/dome.json" 2>"$tmp/err.txt" || fail "render with a PNG inset: $(cat "$tmp/err.txt")"
"$bin/ig-render" "${down[@]}" --colors image --out "$tmp/dome_plain.png" 2>/dev/null ||
    fail "render without the PNG inset"
cmp -s "$tmp/dome_view.png" "$tmp/dome_plain.png" && fail "the PNG inset changed nothing"
python3 - "$tmp/dome.json" <<'PY' || fail "json (PNG inset)"
import json, sys
(i,) = json.load(open(sys.argv[1]))["insets"]
assert i["cells"] == [410, 410, 418, 418] and i["factor"] == 4, i
PY

"$bin/ig-render" --inset synthetic:1,1,2,2,2 --pose 20000,20000,+900,45,-20,0 --size 64x48 \
    --out "$tmp/x.png" 2>"$tmp/err.txt" && fail "a synthetic inset without --synthetic accepted"
grep -q -- "--synthetic" "$tmp/err.txt" || fail "message: $(cat "$tmp/err.txt")"

expect_refused() {  # DESCRIPTION WORDS... -- COMMAND...
    local what=$1; shift
    local words=()
    while [ "$1" != "--" ]; do words+=("$1"); shift; done
    shift
    "$@" >"$tmp/out.txt" 2>&1
    local rc=$?
    [ $rc -eq 2 ] || fail "$what: exit $rc, expected 2: $(cat "$tmp/out.txt")"
    for w in "${words[@]}"; do
        grep -q -- "$w" "$tmp/out.txt" || fail "$what: message lacks '$w': $(cat "$tmp/out.txt")"
    done
}
# The elevation ramp lit by the sun (the synthetic map's default look) over the map and the inset.
"$bin/ig-render" "${common[@]}" --inset synthetic:400,400,128,128,4 --colors ramp --sun 135,30 \
    --out "$tmp/lit.png" 2>/dev/null || fail "render a lit inset"
cmp -s "$tmp/lit.png" "$tmp/nested.png" && fail "the ramp and sun changed nothing"

# A database loaded whole takes a raster inset; one paged beyond --cache-mb refuses it.
"$bin/ig-build-db" --synthetic 512:3 --spacing 8 --tile 32 --out "$tmp/s.db" --quiet >/dev/null ||
    fail "build a database"
"$bin/ig-render" --db "$tmp/s.db" --pose 3312,2950,+300,0,-60,0 --size 160x100 \
    --inset "$tmp/dome.png@410,410,4" --out "$tmp/db_dome.png" 2>/dev/null ||
    fail "render a database with an inset"
cmp -s "$tmp/db_dome.png" "$tmp/dome_view.png" ||
    fail "the database with the inset renders another frame than the map it was built from"
expect_refused "a paged database" "paged" -- "$bin/ig-render" --db "$tmp/s.db" --cache-mb 1 \
    --pose 3312,2950,+300,0,-60,0 --size 160x100 --inset "$tmp/dome.png@410,410,4" \
    --out "$tmp/x.png"

# Insets held in a database: built with the map, or added to a database of it (the same
# bytes); loaded whole and paged through a cache a third of the map's size, the database
# renders the frame the flags render.
"$bin/ig-build-db" --synthetic 1024:3 --spacing 8 --tile 32 --inset synthetic:400,400,128,128,4 \
    --out "$tmp/in.db" --quiet >/dev/null || fail "build a database with an inset"
"$bin/ig-build-db" --synthetic 1024:3 --spacing 8 --tile 32 --out "$tmp/add.db" --quiet \
    >/dev/null || fail "build a database without"
"$bin/ig-build-db" --db "$tmp/add.db" --synthetic 1024:3 --spacing 8 \
    --inset synthetic:400,400,128,128,4 --out "$tmp/add.db" --quiet >/dev/null ||
    fail "add an inset to a database"
cmp -s "$tmp/in.db" "$tmp/add.db" || fail "the inset added differs from the one built in"
abs=(--pose 3600,3000,900,20,-25,0 --size 160x100 --levels auto --colors image)
"$bin/ig-render" --synthetic 1024:3 --spacing 8 --inset synthetic:400,400,128,128,4 "${abs[@]}" \
    --out "$tmp/flags.png" 2>/dev/null || fail "render the inset from the flags"
"$bin/ig-render" --db "$tmp/in.db" "${abs[@]}" --out "$tmp/db_whole.png" 2>/dev/null ||
    fail "render the database with its inset whole"
"$bin/ig-render" --db "$tmp/in.db" --cache-mb 3 "${abs[@]}" --out "$tmp/db_paged.png" \
    --json "$tmp/db_paged.json" 2>/dev/null || fail "render the database with its inset paged"
cmp -s "$tmp/flags.png" "$tmp/db_whole.png" || fail "the database loaded whole renders another frame"
cmp -s "$tmp/flags.png" "$tmp/db_paged.png" || fail "the paged database renders another frame"
python3 - "$tmp/db_paged.json" <<'PY' || fail "json (paged database with an inset)"
import json, sys
j = json.load(open(sys.argv[1]))
(i,) = j["insets"]
assert i["cells"] == [400, 400, 528, 528] and i["factor"] == 4 and i["tiles_read"] > 0, i
assert j["paging"]["tiles_substituted"] == 0, j["paging"]
PY
# A scene over the inset: houses scattered over it and a tank crossing it stand on its surface.
# ig-render draws them the same from the flags, the database loaded whole and paged (image and
# object ids); flythrough's ground truth over the paged database places them as in memory.
root=$(cd "$(dirname "$0")/../.." && pwd)
printf 't,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,3600,2600,700,20,-20,0\n2,3800,3200,700,30,-20,0\n' \
    >"$tmp/traj.csv"
cat >"$tmp/scene.json" <<JSON
{"models": {"house": {"vox": "$root/data/models/house.vox"},
            "tank": {"vox": "$root/data/models/tank.vox"}},
 "objects": [{"id": 1, "model": "tank", "trajectory": "$tmp/tank.csv", "scale": 3}],
 "scatter": [{"model": "house", "count": 150, "area": [3250, 3250, 4150, 4150], "seed": 5,
              "scale": 4, "first_id": 100}]}
JSON
printf 't,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,3000,3400,0,90,0,0\n10,4400,3400,0,90,0,0\n' \
    >"$tmp/tank.csv"
sc=(--scene "$tmp/scene.json" --time 4)
"$bin/ig-render" --synthetic 1024:3 --spacing 8 --inset synthetic:400,400,128,128,4 "${abs[@]}" \
    "${sc[@]}" --out "$tmp/sc_flags.png" --objects-out "$tmp/sc_flags_ids.png" 2>/dev/null ||
    fail "render a scene over the inset from the flags"
"$bin/ig-render" --db "$tmp/in.db" "${abs[@]}" "${sc[@]}" --out "$tmp/sc_whole.png" \
    --objects-out "$tmp/sc_whole_ids.png" 2>/dev/null || fail "render a scene over the database whole"
"$bin/ig-render" --db "$tmp/in.db" --cache-mb 3 "${abs[@]}" "${sc[@]}" --out "$tmp/sc_paged.png" \
    --objects-out "$tmp/sc_paged_ids.png" 2>/dev/null || fail "render a scene over the database paged"
cmp -s "$tmp/sc_flags.png" "$tmp/flags.png" && fail "the scene over the inset drew nothing"
for v in whole paged; do
    cmp -s "$tmp/sc_flags.png" "$tmp/sc_$v.png" || fail "the scene over the database ($v) differs"
    cmp -s "$tmp/sc_flags_ids.png" "$tmp/sc_${v}_ids.png" ||
        fail "the object ids over the database ($v) differ"
done
for where in paged memory; do
    terrain=(--db "$tmp/in.db" --cache-mb 8)
    [ $where = memory ] && terrain=(--synthetic 1024:3 --spacing 8 --inset synthetic:400,400,128,128,4)
    msg=$("$bin/flythrough" "${terrain[@]}" --trajectory "$tmp/traj.csv" \
        --scene "$tmp/scene.json" --truth "$tmp/truth_$where.jsonl" --clock simulated \
        --size 160x120 --margin 8 --render-threads 1 --out null --contact none \
        --json "$tmp/fly_scene_$where.json" 2>&1) || fail "a scene over the inset ($where): $msg"
done
python3 - "$tmp/truth_paged.jsonl" "$tmp/truth_memory.jsonl" "$tmp/fly_scene_paged.json" <<'PY' ||
import json, sys
a = [json.loads(l) for l in open(sys.argv[1])]
b = [json.loads(l) for l in open(sys.argv[2])]
assert len(a) == len(b) == 120, (len(a), len(b))
pairs = 0
for x, y in zip(a, b):
    ox = {o["id"]: o for o in x["objects"]}
    oy = {o["id"]: o for o in y["objects"]}
    assert set(ox) == set(oy), (x["field"], set(ox) ^ set(oy))
    for i in ox:
        assert ox[i]["true_bbox"] == oy[i]["true_bbox"], (x["field"], ox[i], oy[i])
        pairs += 1
assert pairs > 1000, pairs
j = json.load(open(sys.argv[3]))
assert j["fields"] == 120 and j["missed_deadlines"] == 0, (j["fields"], j["missed_deadlines"])
print("truth over the inset: %d objects placed the same paged and in memory" % pairs)
PY
    fail "the truth over the paged inset"

expect_refused "a flag inset over a database holding one" "holds insets" -- "$bin/ig-render" \
    --db "$tmp/in.db" "${abs[@]}" --inset synthetic:10,10,8,8,2 --out "$tmp/x.png"
expect_refused "an inset next to one the database holds" "holds already" -- \
    "$bin/ig-build-db" --db "$tmp/in.db" --synthetic 1024:3 --spacing 8 \
    --inset synthetic:530,400,8,8,2 --out "$tmp/x.db" --quiet
expect_refused "a synthetic inset over another generator's map" "is not" -- \
    "$bin/ig-build-db" --db "$tmp/in.db" --synthetic 512:3 --spacing 8 \
    --inset synthetic:10,10,8,8,2 --out "$tmp/x.db" --quiet
[ -e "$tmp/x.db" ] && fail "a refused build wrote its output"

expect_refused "a factor of 3" "FACTOR" -- "$bin/ig-render" "${common[@]}" \
    --inset synthetic:400,400,16,16,3 --out "$tmp/x.png"
expect_refused "an inset off the map" "outside" -- "$bin/ig-render" "${common[@]}" \
    --inset synthetic:1000,1000,64,64,2 --out "$tmp/x.png"
expect_refused "two insets that touch" "touches" -- "$bin/ig-render" "${common[@]}" \
    --inset synthetic:400,400,16,16,2 --inset synthetic:416,400,16,16,2 --out "$tmp/x.png"
expect_refused "the span caster" "span" -- "$bin/ig-render" "${common[@]}" \
    --inset synthetic:400,400,16,16,2 --caster span --out "$tmp/x.png"
expect_refused "a raster that does not exist" "nothere.tif" -- "$bin/ig-render" "${common[@]}" \
    --inset "$tmp/nothere.tif@10,10,2" --out "$tmp/x.png"
expect_refused "a raster without a georeference or a place" "georeference" -- \
    "$bin/ig-render" "${common[@]}" --inset "$tmp/dome.png" --out "$tmp/x.png"
[ -e "$tmp/x.png" ] && fail "a refused run wrote its output"

# flythrough over the inset on the simulated field clock: every field, none missed.
printf 't,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,3600,2600,700,20,-20,0\n2,3800,3200,700,30,-20,0\n' \
    >"$tmp/traj.csv"
for renderer in thread process; do
    msg=$("$bin/flythrough" --synthetic 1024:3 --spacing 8 --inset synthetic:400,400,128,128,4 \
        --trajectory "$tmp/traj.csv" --renderer $renderer --clock simulated --out null \
        --contact none --json "$tmp/fly.json" 2>&1) || fail "fly ($renderer): $msg"
    python3 - "$tmp/fly.json" <<'PY' || fail "fly ($renderer): $msg"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["fields"] == 120, j["fields"]
assert j["missed_deadlines"] == 0, j["missed_deadlines"]
assert j["frames_rendered"] > 10, j["frames_rendered"]
PY
done
# A stick flight starts and flies over the ground under the inset.
"$bin/flythrough" --synthetic 1024:3 --spacing 8 --inset synthetic:400,400,128,128,4 \
    --start 3600,2800,+40,20 --clock simulated --duration 2 --out null --contact none \
    >/dev/null 2>&1 || fail "stick flight over an inset"
# flythrough over the database's inset, loaded whole and paged (in a thread and in a renderer
# process), and a stick flight standing on the paged inset's ground.
for run in "whole thread" "paged thread" "paged process"; do
    set -- $run
    cache=()
    [ "$1" = paged ] && cache=(--cache-mb 8)
    msg=$("$bin/flythrough" --db "$tmp/in.db" "${cache[@]}" --trajectory "$tmp/traj.csv" \
        --renderer "$2" --clock simulated --out null --contact none --json "$tmp/fly.json" 2>&1) ||
        fail "fly the database's inset ($run): $msg"
    python3 - "$tmp/fly.json" "$1" <<'PY' || fail "fly the database's inset ($run): $msg"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["fields"] == 120 and j["missed_deadlines"] == 0, (j["fields"], j["missed_deadlines"])
assert j["frames_rendered"] > 10, j["frames_rendered"]
assert ("paging" in j) == (sys.argv[2] == "paged"), sys.argv[2]
PY
done
"$bin/flythrough" --db "$tmp/in.db" --cache-mb 8 --start 3600,2800,+40,20 --clock simulated \
    --duration 2 --out null --contact none >/dev/null 2>&1 || fail "stick flight over a paged inset"
# Stereo pairs over the inset: ig-render's pair from the flags, the database loaded whole and
# paged are the same images; the inset changes both eyes. flythrough flies pairs over it (a
# scene's objects on it, in memory and paged), every field on time.
st=(--stereo 12 --size 160x100 --pose 3600,3000,900,20,-25,0 --levels auto --colors image)
for v in flags whole paged plain; do
    terrain=(--synthetic 1024:3 --spacing 8 --inset synthetic:400,400,128,128,4)
    [ $v = whole ] && terrain=(--db "$tmp/in.db")
    [ $v = paged ] && terrain=(--db "$tmp/in.db" --cache-mb 3)
    [ $v = plain ] && terrain=(--synthetic 1024:3 --spacing 8)
    "$bin/ig-render" "${terrain[@]}" "${st[@]}" --out-left "$tmp/st_${v}_l.png" \
        --out-right "$tmp/st_${v}_r.png" 2>"$tmp/err.txt" ||
        fail "a stereo pair over the inset ($v): $(cat "$tmp/err.txt")"
done
for v in whole paged; do
    for e in l r; do
        cmp -s "$tmp/st_flags_$e.png" "$tmp/st_${v}_$e.png" ||
            fail "the pair's $e eye over the database ($v) differs from the flags'"
    done
done
cmp -s "$tmp/st_flags_r.png" "$tmp/st_plain_r.png" && fail "the inset changed nothing in the right eye"
cmp -s "$tmp/st_flags_l.png" "$tmp/st_flags_r.png" && fail "the right eye is the left"
for run in "flags thread" "whole thread" "paged thread" "paged process" "scene thread" \
    "pagedscene process"; do
    set -- $run
    terrain=(--synthetic 1024:3 --spacing 8 --inset synthetic:400,400,128,128,4)
    [ "$1" = whole ] && terrain=(--db "$tmp/in.db")
    [ "$1" = paged ] && terrain=(--db "$tmp/in.db" --cache-mb 8)
    [ "$1" = scene ] && terrain+=(--scene "$tmp/scene.json")
    [ "$1" = pagedscene ] && terrain=(--db "$tmp/in.db" --cache-mb 8 --scene "$tmp/scene.json")
    msg=$("$bin/flythrough" "${terrain[@]}" --trajectory "$tmp/traj.csv" --stereo 12 \
        --renderer "$2" --clock simulated --size 160x120 --out "y4m:$tmp/st_$1.y4m" --contact none \
        --json "$tmp/fly.json" 2>&1) || fail "fly pairs over the inset ($run): $msg"
    python3 - "$tmp/fly.json" <<'PY' || fail "fly pairs over the inset ($run): $msg"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["fields"] == 120 and j["missed_deadlines"] == 0, (j["fields"], j["missed_deadlines"])
assert j["stereo"]["separation_m"] == 12, j["stereo"]
PY
done
cmp -s "$tmp/st_flags.y4m" "$tmp/st_whole.y4m" ||
    fail "the pairs flown over the database loaded whole differ from the flags'"
# A CIGI host flying over the inset: its HAT/HOT requests and lines of sight are answered on the
# nested surface, from the flags in memory and from the paged database (a thread of its own
# reading the inset's tiles too); every field on time, every answer valid.
for where in memory paged; do
    terrain=(--synthetic 1024:3 --spacing 8 --inset synthetic:400,400,128,128,4)
    [ $where = paged ] && terrain=(--db "$tmp/in.db" --cache-mb 8)
    rm -f "$tmp/port" "$tmp/host.json"
    "$bin/cigi-host" --port-file "$tmp/port" --seconds 4 --queries 4 --origin 47,-122,0 \
        --start 3300,3300,900 --speed 100 --pitch 0 --json "$tmp/host.json" 2>"$tmp/host.err" &
    hpid=$!
    for i in $(seq 1 300); do [ -s "$tmp/port" ] && break; sleep 0.1; done
    [ -s "$tmp/port" ] || fail "cigi-host wrote no port"
    msg=$("$bin/flythrough" "${terrain[@]}" --renderer thread --cigi 127.0.0.1:0 \
        --cigi-host "127.0.0.1:$(cat "$tmp/port")" --cigi-origin 47,-122 --cigi-wait 10 \
        --duration 3 --size 160x120 --margin 8 --render-threads 1 --out null --contact none \
        --json "$tmp/cigi.json" 2>&1) || fail "cigi over the inset ($where): $msg"
    wait "$hpid" || fail "cigi-host ($where): $(cat "$tmp/host.err")"
    python3 - "$tmp/cigi.json" "$tmp/host.json" <<'PY' || fail "cigi over the inset ($where): $msg"
import json, sys
j = json.load(open(sys.argv[1]))
h = json.load(open(sys.argv[2]))["queries"]
assert j["fields"] == 180 and j["missed_deadlines"] == 0, (j["fields"], j["missed_deadlines"])
assert j["cigi"]["unknown_terrain_answers"] == 0, j["cigi"]
assert h["hat_hot_answers"] >= 240 and h["los_answers"] >= 60, h
assert h["valid"] == h["hat_hot_answers"] + h["los_answers"], h
PY
done
echo "insets: ok"
