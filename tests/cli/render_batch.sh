#!/usr/bin/env bash
# ig-render --poses: twelve poses in one call give the same colour PNGs and depth PFMs, byte for
# byte, as twelve single calls, whatever the thread count; the JSON holds one record per frame.
# Usage: render_batch.sh BIN_DIR TMP_DIR DATA_DIR
set -u
bin="$1"; dir="$2/render_batch"
rm -rf "$dir"; mkdir -p "$dir"
render="$bin/ig-render"
common=(--synthetic 128:7 --size 96x64 --haze 800 --sun 200,30 --supersample auto)
poses="$dir/poses.txt"
{
    echo "# x,y,z,yaw,pitch,roll"
    for k in 0 1 2 3 4 5 6 7 8 9 10 11; do
        echo "$((200 + 40 * k)),$((300 + 25 * k)),+$((60 + 30 * k)),$((30 * k)),-$((3 + 7 * k)),0"
    done
} > "$poses"
fail() { echo "FAIL ($*)"; exit 1; }
"$render" "${common[@]}" --poses "$poses" --threads 1 --out "$dir/a_##.png" \
    --depth "$dir/a_##.pfm" --json "$dir/a.json" 2>/dev/null || fail "batch, 1 thread"
"$render" "${common[@]}" --poses "$poses" --threads 3 --out "$dir/b_##.png" \
    --depth "$dir/b_##.pfm" 2>/dev/null || fail "batch, 3 threads"
k=0
grep -v '^#' "$poses" | while read -r pose; do
    n=$(printf "%02d" "$k")
    "$render" "${common[@]}" --pose "$pose" --out "$dir/s_$n.png" --depth "$dir/s_$n.pfm" \
        2>/dev/null || fail "single call $k"
    for ext in png pfm; do
        cmp -s "$dir/a_$n.$ext" "$dir/s_$n.$ext" || fail "frame $k .$ext: batch differs from single"
        cmp -s "$dir/a_$n.$ext" "$dir/b_$n.$ext" || fail "frame $k .$ext: 1 and 3 threads differ"
    done
    k=$((k + 1))
done || exit 1
frames=$(grep -c '"index"' "$dir/a.json")
[ "$frames" -eq 12 ] || fail "JSON has $frames frame records, expected 12"
# A trajectory CSV every 2 s over its 8 s: frames at 0, 2, 4, 6, 8 s.
"$render" --size 64x48 --poses "$3/trajectories/straight.csv" --every 2 --out "$dir/t_#.png" \
    --json "$dir/t.json" 2>/dev/null || fail "trajectory batch"
frames=$(grep -c '"index"' "$dir/t.json")
[ "$frames" -eq 5 ] && [ -e "$dir/t_4.png" ] || fail "trajectory: $frames frames, expected 5"
echo "ok: 12 frames equal to 12 single calls (1 and 3 threads); a trajectory every 2 s"
