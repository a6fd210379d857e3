#!/usr/bin/env bash
# Programs against a hostile but fair user: outputs that must not replace what they should not,
# inputs that must not stall a run, signals that must end a run cleanly.
# Usage: hostile.sh CASE BIN_DIR DATA_DIR
set -u
case_name="$1"; bin="$2"; data="$3"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/vig_hostile_${case_name}_XXXXXX")
trap 'rm -rf "$tmp"' EXIT
render="$bin/ig-render"; fly="$bin/flythrough"; warp="$bin/warp-eval"; check="$bin/io-check"
stereo="$bin/stereo-eval"

fail() { echo "FAIL ($case_name): $*"; exit 1; }
# Runs a command that must fail cleanly: exit 1..127, stderr matching PATTERN. Sets $msg.
must_refuse() {
    local pattern="$1"; shift
    msg=$("$@" 2>&1 >/dev/null); local rc=$?
    [ "$rc" -ne 0 ] || fail "exit 0 for: $*"
    [ "$rc" -lt 124 ] || fail "exit $rc (crash or timeout) for: $*"
    grep -Eq -- "$pattern" <<<"$msg" || fail "message /$pattern/ not in: $msg"
}
# Waits (up to 60 s) until FILE (or FILE.part) holds at least BYTES bytes: the run is under way.
wait_for_bytes() {
    local file="$1" bytes="$2" i
    for i in $(seq 1 600); do
        for f in "$file" "$file.part"; do
            [ -f "$f" ] && [ "$(stat -c %s "$f")" -ge "$bytes" ] && return 0
        done
        sleep 0.1
    done
    fail "$file: still under $bytes bytes after 60 s"
}
# Waits (up to 30 s) until process PID, running PROGRAM, catches SIGINT and SIGTERM (its SigCgt mask in
# /proc): a signal sent after this is the program's to handle, not the default death of a
# process still starting.
# The shell's forked child shows the shell's own handlers until it has run the program (and a
# background child of a script ignores SIGINT until then), so the mask counts only once the
# process is the program itself.
wait_for_handlers() {
    local pid="$1" program i mask
    program=$(readlink -f "$2")
    for i in $(seq 1 600); do
        mask=""
        [ "$(readlink -f "/proc/$pid/exe" 2>/dev/null)" = "$program" ] &&
            mask=$(awk '/^SigCgt:/ {print $2}' "/proc/$pid/status" 2>/dev/null) || true
        [ -n "$mask" ] && [ $((0x$mask & 0x4002)) -eq $((0x4002)) ] && return 0
        sleep 0.05
    done
    fail "process $pid installed no SIGINT/SIGTERM handler in 30 s"
}
# Frames in a Y4M as ffprobe (FFmpeg, another implementation) decodes them; ffprobe is
# installed by scripts/setup.sh, and its absence is a failure, not a skip.
ffprobe_frames() {
    command -v ffprobe >/dev/null || fail "ffprobe not installed (scripts/setup.sh installs ffmpeg)"
    ffprobe -v error -count_frames -select_streams v:0 -show_entries stream=nb_read_frames \
        -of csv=p=0 "$1" 2>"$tmp/ffprobe.err" || fail "ffprobe refused $1: $(cat "$tmp/ffprobe.err")"
}
# Y4M size check: header line plus whole frames of W x H 4:2:2 (2 bytes a pixel) + "FRAME\n".
whole_frames() {
    local file="$1" w="$2" h="$3"
    local header; header=$(head -c 200 "$file" | head -n 1 | wc -c)
    local size; size=$(stat -c %s "$file")
    local frame=$((w * h * 2 + 6))
    [ $(((size - header) % frame)) -eq 0 ] || fail "$file: $size bytes is not whole frames"
    echo $(((size - header) / frame))
}
# Waits (up to 30 s) for cigi-host to write its port.
wait_for_port() {
    local i
    for i in $(seq 1 300); do [ -s "$1" ] && return 0; sleep 0.1; done
    fail "cigi-host wrote no port to $1"
}
fly_small=(--size 160x120 --margin 8 --render-threads 1 --quiet)

case "$case_name" in
# 1. A device node, a symlink: written through, never replaced.
device_and_symlink_outputs)
    mknod "$tmp/n" c 1 3 || { echo "SKIP: mknod not permitted"; exit 0; }
    "$render" --size 160x120 --out "$tmp/n" --json "$tmp/n" --depth "$tmp/n" 2>/dev/null ||
        fail "ig-render to a device node failed"
    [ -c "$tmp/n" ] || fail "ig-render replaced the device node"
    "$fly" "${fly_small[@]}" --clock simulated --duration 0.2 --out "y4m:$tmp/n" --contact "$tmp/n" \
        --json "$tmp/n" >/dev/null 2>&1 || fail "flythrough to a device node failed"
    [ -c "$tmp/n" ] || fail "flythrough replaced the device node"
    mkdir "$tmp/real"; echo old > "$tmp/real/f.png"; ln -s real/f.png "$tmp/link.png"
    "$render" --size 160x120 --out "$tmp/link.png" 2>/dev/null || fail "ig-render to a symlink failed"
    [ -L "$tmp/link.png" ] || fail "the symlink was replaced"
    head -c 4 "$tmp/real/f.png" | grep -q PNG || fail "the symlink's target was not written"
    ;;
# 2. Trajectory times so large that t + step == t: the start-up check must still end.
trajectory_huge_times)
    printf 't,x,y,z,yaw_deg,pitch_deg,roll_deg\n1e16,80000,80000,3000,0,-5,0\n10000000000000004,80100,80000,3000,0,-5,0\n' \
        > "$tmp/t.csv"
    timeout -s KILL 60 "$fly" "${fly_small[@]}" --clock simulated --out null --contact none --duration 1 \
        --trajectory "$tmp/t.csv" >/dev/null 2>"$tmp/err"; rc=$?
    [ "$rc" -ne 137 ] || fail "flythrough hung on a trajectory at t = 1e16"
    [ "$rc" -lt 124 ] || fail "flythrough crashed (exit $rc)"
    [ "$rc" -eq 2 ] || fail "flythrough accepted times of 1e16 s (exit $rc)"
    grep -q "t.csv.*out of range" "$tmp/err" || fail "an error that does not name the file and the range: $(cat "$tmp/err")"
    timeout -s KILL 60 "$warp" --trajectory "$tmp/t.csv" --frames 1 --horizons 1 --models poly --repeats 1 \
        --size 64x48 >/dev/null 2>"$tmp/err"; rc=$?
    [ "$rc" -ne 137 ] || fail "warp-eval hung on a trajectory at t = 1e16"
    [ "$rc" -lt 124 ] || fail "warp-eval crashed (exit $rc)"
    [ "$rc" -eq 2 ] && grep -q "t.csv.*out of range" "$tmp/err" || fail "warp-eval: $(cat "$tmp/err")"
    ;;
# 3. A small --render-hz: the run still ends at --duration.
small_render_rate)
    start=$(date +%s%N)
    timeout -s KILL 30 "$fly" "${fly_small[@]}" --duration 0.5 --render-hz 0.1 --out null --contact none \
        --json "$tmp/s.json" >/dev/null 2>&1 || fail "flythrough --render-hz 0.1 failed or hung"
    took_ms=$((($(date +%s%N) - start) / 1000000))
    [ "$took_ms" -lt 5000 ] || fail "a 0.5 s run took $took_ms ms"
    # 12. Stats that agree: every shown frame was rendered.
    python3 - "$tmp/s.json" <<'EOF' || fail "stats disagree: $(cat "$tmp/s.json")"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["frames_rendered"] >= j["frames_shown"] >= 1, j
assert j["render_fps"] > 0, j
EOF
    timeout -s KILL 30 "$fly" "${fly_small[@]}" --clock simulated --duration 0.5 --render-hz 0.01 --out null \
        --contact none >/dev/null 2>&1 || fail "simulated --render-hz 0.01 failed or hung"
    must_refuse "--render-hz" "$fly" --render-hz 1e-6 --out null --contact none --duration 0.1
    must_refuse "--render-hz" "$fly" --render-hz nan --out null --contact none --duration 0.1
    ;;
# 4. Standard output carries one document, whole.
stdout_is_one_document)
    "$fly" "${fly_small[@]}" --clock simulated --duration 0.5 --out y4m:- --contact none \
        > "$tmp/v.y4m" 2>/dev/null || fail "flythrough --out y4m:- failed"
    frames=$(whole_frames "$tmp/v.y4m" 160 120)
    [ "$frames" -ge 14 ] || fail "only $frames frames on standard output"
    must_refuse "standard output" "$fly" --out y4m:- --json - --contact none --duration 0.1
    must_refuse "standard output" "$render" --size 64x48 --out - --json -
    ;;
# 5. An output on an input is refused before any work, the input untouched.
output_on_input)
    cp "$data/puget-sound-1k/ps_height_1k.png" "$tmp/v.png"
    before=$(md5sum < "$tmp/v.png")
    must_refuse "same file as the input --height" "$render" --height "$tmp/v.png" --out "$tmp/v.png"
    must_refuse "same file as the input --height" "$render" --height "$tmp/v.png" --out "$tmp/./v.png"
    [ "$(md5sum < "$tmp/v.png")" = "$before" ] || fail "the height map was changed"
    cp "$data/trajectories/straight.csv" "$tmp/t.csv"
    before=$(md5sum < "$tmp/t.csv")
    must_refuse "same file as the input --trajectory" "$fly" --trajectory "$tmp/t.csv" \
        --json "$tmp/t.csv" --out null --contact none
    [ "$(md5sum < "$tmp/t.csv")" = "$before" ] || fail "the trajectory was changed"
    must_refuse "same file as --out" "$fly" --out "y4m:$tmp/x" --contact "$tmp/x" --duration 0.1
    [ ! -e "$tmp/x" ] || fail "a file was left at $tmp/x"
    ;;
# 6. SIGINT / SIGTERM: the field in hand finishes, every output is written, 130 / 143.
signals_end_runs_cleanly)
    for sig in INT TERM; do
        rm -f "$tmp"/v.y4m* "$tmp"/s.json* "$tmp"/c.png*
        "$fly" "${fly_small[@]}" --duration 60 --out "y4m:$tmp/v.y4m" --json "$tmp/s.json" \
            --contact "$tmp/c.png" >/dev/null 2>&1 &
        pid=$!
        wait_for_bytes "$tmp/v.y4m" 100000  # a few frames in, however loaded the machine
        kill -s "$sig" "$pid"
        wait "$pid"; rc=$?
        want=$([ "$sig" = INT ] && echo 130 || echo 143)
        [ "$rc" -eq "$want" ] || fail "SIG$sig: exit $rc, expected $want"
        frames=$(whole_frames "$tmp/v.y4m" 160 120)
        [ "$frames" -ge 1 ] || fail "SIG$sig: no frame in the video"
        python3 -c "import json,sys; j=json.load(open(sys.argv[1])); assert j['fields'] > 0" \
            "$tmp/s.json" || fail "SIG$sig: no valid JSON"
        head -c 4 "$tmp/c.png" | grep -q PNG || fail "SIG$sig: no contact sheet"
        ls "$tmp" | grep -q '\.part$' && fail "SIG$sig: a .part file was left"
    done
    # A second signal ends the run at once: the video is still whole frames.
    rm -f "$tmp"/v.y4m*
    "$fly" "${fly_small[@]}" --duration 60 --out "y4m:$tmp/v.y4m" --contact none \
        --render-hz 1 >/dev/null 2>&1 &
    pid=$!
    wait_for_bytes "$tmp/v.y4m" 100000
    kill -s INT "$pid"; kill -s INT "$pid"
    wait "$pid"; rc=$?
    [ "$rc" -eq 130 ] || fail "two SIGINTs: exit $rc"
    whole_frames "$tmp/v.y4m" 160 120 >/dev/null
    ls "$tmp" | grep -q '\.part$' && fail "two SIGINTs: a .part file was left"
    # io-check pattern likewise.
    "$check" pattern --out "y4m:$tmp/p.y4m" --size 160x120 --duration 60 --json "$tmp/p.json" \
        >/dev/null 2>&1 &
    pid=$!
    wait_for_bytes "$tmp/p.y4m" 100000
    kill -s TERM "$pid"
    wait "$pid"; rc=$?
    [ "$rc" -eq 143 ] || fail "io-check pattern SIGTERM: exit $rc"
    whole_frames "$tmp/p.y4m" 160 120 >/dev/null
    python3 -c "import json,sys; json.load(open(sys.argv[1]))" "$tmp/p.json" ||
        fail "io-check pattern: no valid JSON"
    ;;
# The renderer process fails in every way it can: the fields go on, the video is whole.
renderer_faults)
    for fault in crash@1 segv@1 exception@1 hang@1 stall@1:4000 garbage@1; do
        rm -f "$tmp"/v.y4m "$tmp"/s.json
        timeout -s KILL 120 "$fly" "${fly_small[@]}" --clock simulated --duration 3 \
            --out "y4m:$tmp/v.y4m" --json "$tmp/s.json" --contact none --render-timeout-ms 1500 \
            --inject-renderer-fault "$fault" >/dev/null 2>"$tmp/err"; rc=$?
        [ "$rc" -eq 0 ] || fail "$fault: exit $rc: $(cat "$tmp/err")"
        frames=$(whole_frames "$tmp/v.y4m" 160 120)
        [ "$frames" -eq 90 ] || fail "$fault: $frames frames, expected 90"
        frames=$(ffprobe_frames "$tmp/v.y4m")
        [ "$frames" = 90 ] || fail "$fault: ffprobe read $frames frames, expected 90"
        python3 - "$tmp/s.json" "$fault" <<'PY' || fail "$fault: $(cat "$tmp/s.json")"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["fields"] == 180, j["fields"]
assert j["missed_deadlines"] == 0
r = j["renderer_restarts"]
assert len(r) == 1, r
assert r[0]["gap_ms"] is not None and r[0]["gap_ms"] > 0, r
PY
    done
    # Wall clock: the renderer process killed from outside mid-run.
    "$fly" "${fly_small[@]}" --duration 8 --out "y4m:$tmp/w.y4m" --json "$tmp/w.json" \
        --contact none >/dev/null 2>"$tmp/err" &
    pid=$!
    wait_for_bytes "$tmp/w.y4m" 100000  # under way, however loaded the machine
    child=$(pgrep -P "$pid" | head -n 1)
    [ -n "$child" ] || fail "no renderer process under flythrough $pid"
    kill -9 "$child"
    wait "$pid"; rc=$?
    [ "$rc" -eq 0 ] || fail "renderer killed: exit $rc: $(cat "$tmp/err")"
    frames=$(whole_frames "$tmp/w.y4m" 160 120)
    [ "$frames" -eq 240 ] || fail "renderer killed: $frames frames, expected 240"
    frames=$(ffprobe_frames "$tmp/w.y4m")
    [ "$frames" = 240 ] || fail "renderer killed: ffprobe read $frames frames, expected 240"
    python3 - "$tmp/w.json" <<'PY' || fail "renderer killed: $(cat "$tmp/w.json")"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["fields"] == 480, j["fields"]
r = j["renderer_restarts"]
assert len(r) == 1 and "signal 9" in r[0]["cause"], r
PY
    # A renderer hung for good does not hold up the end: SIGINT still ends the run at once with
    # every output written.
    rm -f "$tmp"/h.y4m "$tmp"/h.json
    "$fly" "${fly_small[@]}" --duration 60 --out "y4m:$tmp/h.y4m" --json "$tmp/h.json" \
        --contact none --render-timeout-ms 60000 --inject-renderer-fault hang@0.5 \
        >/dev/null 2>"$tmp/err" &
    pid=$!
    wait_for_bytes "$tmp/h.y4m" 1000000  # well past the hang: fields go on without frames
    renderer=$(pgrep -P "$pid" | head -n 1)
    [ -n "$renderer" ] || fail "hung renderer: no renderer process under flythrough $pid"
    start=$(date +%s%N)
    kill -s INT "$pid"
    wait "$pid"; rc=$?
    ms=$((($(date +%s%N) - start) / 1000000))
    [ "$rc" -eq 130 ] || fail "hung renderer, SIGINT: exit $rc: $(cat "$tmp/err")"
    [ "$ms" -lt 5000 ] || fail "hung renderer, SIGINT: the run took $ms ms to end"
    frames=$(whole_frames "$tmp/h.y4m" 160 120)
    [ "$(ffprobe_frames "$tmp/h.y4m")" = "$frames" ] || fail "hung renderer, SIGINT: ffprobe disagrees"
    python3 -c "import json,sys; json.load(open(sys.argv[1]))" "$tmp/h.json" ||
        fail "hung renderer, SIGINT: no valid JSON"
    sleep 0.2
    kill -0 "$renderer" 2>/dev/null && fail "hung renderer, SIGINT: its process $renderer was left"
    ;;
# SIGINT or SIGTERM at any instant of a run: the video is whole frames, the JSON is written.
signals_at_random_instants)
    for i in $(seq 1 20); do
        rm -f "$tmp"/v.y4m* "$tmp"/s.json*
        sig=$([ $((i % 2)) -eq 0 ] && echo INT || echo TERM)
        "$fly" "${fly_small[@]}" --duration 30 --out "y4m:$tmp/v.y4m" --json "$tmp/s.json" \
            --contact none >/dev/null 2>&1 &
        pid=$!
        # Once the program has installed its handlers (however loaded the machine), at a
        # random instant from then to 1.7 s later: loading, the first frame, the fields.
        wait_for_handlers "$pid" "$fly"
        sleep "$((RANDOM % 2)).$((RANDOM % 7))$((RANDOM % 10))"
        kill -s "$sig" "$pid"
        wait "$pid"; rc=$?
        want=$([ "$sig" = INT ] && echo 130 || echo 143)
        [ "$rc" -eq "$want" ] || fail "run $i SIG$sig: exit $rc"
        whole_frames "$tmp/v.y4m" 160 120 >/dev/null
        python3 -c "import json,sys; json.load(open(sys.argv[1]))" "$tmp/s.json" ||
            fail "run $i SIG$sig: no valid JSON"
        ls "$tmp" | grep -q '\.part$' && fail "run $i SIG$sig: a .part file was left"
    done
    ;;
# 7. A png:DIR holding an earlier run is refused unless --overwrite.
png_folder_reuse)
    "$check" pattern --out "png:$tmp/d:1" --size 64x48 --duration 0.2 --clock simulated \
        >/dev/null 2>&1 || fail "first run failed"
    must_refuse "not empty.*--overwrite" "$check" pattern --out "png:$tmp/d:1" --size 64x48 \
        --duration 0.1 --clock simulated
    must_refuse "not empty.*--overwrite" "$fly" "${fly_small[@]}" --out "png:$tmp/d:1" \
        --duration 0.1 --contact none
    "$check" pattern --out "png:$tmp/d:1" --size 64x48 --duration 0.1 --clock simulated \
        --overwrite >/dev/null 2>&1 || fail "--overwrite refused"
    ;;
# 8. NaN is refused, not taken for "off".
stereo_nan)
    must_refuse "--stereo" "$render" --size 64x48 --stereo nan --out-left "$tmp/l.png" \
        --out-right "$tmp/r.png"
    [ ! -e "$tmp/l.png" ] || fail "a frame was written"
    must_refuse "--stereo" "$stereo" --stereo inf --sweep 2 --size 64x48
    ;;
# 9. Messages that name the path, the operation and the reason, readably and bounded.
clear_messages)
    [ -w /dev/full ] && must_refuse "/dev/full.*(No space left|space)" "$fly" "${fly_small[@]}" \
        --clock simulated --duration 0.5 --out y4m:/dev/full --contact none
    must_refuse "png:/proc.*(denied|not permitted|No such|Read-only|cannot)" "$fly" \
        "${fly_small[@]}" --out png:/proc/vig --duration 0.1 --contact none
    must_refuse "--size 1x1.*2\.\.8192 lines" "$fly" --size 1x1 --out null --duration 0.1
    printf '500000,5200000,3000,0,-5,0\n' > "$tmp/poses.txt"
    must_refuse "far off the map" "$stereo" --poses "$tmp/poses.txt" --size 64x48
    must_refuse "'abc' is not a finite number" "$render" --pose 1,2,abc,0,0,0 --out "$tmp/f.png"
    ;;
# 10. Numbers that make no physical sense are refused readably.
terrain_ranges)
    h="$data/puget-sound-1k/ps_height_1k.png"
    for flag in --spacing --height-scale --height-offset --void-height; do
        must_refuse "^ig-render: $flag: 1e\+300 is outside" "$render" --height "$h" "$flag" 1e300 \
            --out "$tmp/f.png"
        [ ${#msg} -lt 200 ] || fail "$flag: a ${#msg}-byte message"
    done
    must_refuse "--spacing" "$render" --height "$h" --spacing -1 --out "$tmp/f.png"
    ;;
# 11. io-check stick and pattern check their numbers and paths before running.
io_check_numbers)
    printf '0 axis pitch 0.1\n' > "$tmp/s.stick"
    for rate in 0 -5 nan inf; do
        must_refuse "--rate" "$check" stick "script:$tmp/s.stick" --rate "$rate" --duration 0.1
    done
    must_refuse "--duration" "$check" stick "script:$tmp/s.stick" --duration -1
    start=$(date +%s)
    must_refuse "/proc" "$check" pattern --out null --duration 5 --json /proc/vig.json
    [ $(($(date +%s) - start)) -lt 3 ] || fail "pattern --json /proc failed only after the run"
    ;;
# 12. A start under the ground is refused.
start_underground)
    must_refuse "--start.*not above the terrain" "$fly" --start 80000,80000,-100,0 --out null \
        --duration 0.1 --contact none
    ;;
cigi_garbage_host)
    # A "host" sending garbage and half-right datagrams during a wall-clock run: every field
    # still leaves, the run ends normally, and the JSON counts what it refused.
    "$fly" --synthetic 128 --cigi 127.0.0.1:0 --cigi-host 127.0.0.1:9 --cigi-origin 47,-122 \
        --duration 2 --out null --contact none --json "$tmp/run.json" "${fly_small[@]}" \
        2>"$tmp/err" &
    pid=$!
    port=""
    for _ in $(seq 200); do
        port=$(grep -o 'CIGI on 127\.0\.0\.1:[0-9]*' "$tmp/err" | grep -o '[0-9]*$')
        [ -n "$port" ] && break
        sleep 0.05
    done
    [ -n "$port" ] || { kill "$pid"; fail "no CIGI port announced: $(cat "$tmp/err")"; }
    for i in $(seq 200); do
        printf 'garbage %d' "$i" >"/dev/udp/127.0.0.1/$port"
        # IG Control's first bytes, cut short.
        printf '\x01\x18\x03\x00\x31\x00\x80\x00' >"/dev/udp/127.0.0.1/$port"
    done
    wait "$pid" || fail "flythrough exited $?: $(cat "$tmp/err")"
    grep -q '"fields": 120' "$tmp/run.json" || fail "not every field: $(cat "$tmp/run.json")"
    bad=$(grep -o '"bad_datagrams": [0-9]*' "$tmp/run.json" | grep -o '[0-9]*$')
    # (a burst beyond the socket buffer, about 256 small datagrams, is dropped by the kernel)
    [ "${bad:-0}" -ge 100 ] || fail "refused datagrams not counted ($bad): $(cat "$tmp/err")"
    grep -q 'cigi: CIGI message from the host' "$tmp/err" || fail "no refusal reported: $(cat "$tmp/err")"
    ;;
# The renderer gap against an instant measured outside the program: this script SIGKILLs the
# renderer process itself, reading CLOCK_MONOTONIC (Python's time.monotonic) just before, and
# compares with the restart flythrough reports (its instants on the same clock). The supervisor
# looks every 2 ms, so it notices within 50 ms even on a loaded machine; the first new frame is
# shown after the kill; and the reported gap (from the field that first showed the last frame
# rendered before the kill to the one that first showed the next) lies between
# kill-to-first-frame less a field period (that last frame may first be shown just after the
# kill) and kill-to-first-frame plus a frame interval (1/render rate, capped at 20 Hz here), a
# field period and 20 ms of scheduling slack.
renderer_gap_from_outside)
    "$fly" "${fly_small[@]}" --render-hz 20 --duration 5 --out "y4m:$tmp/g.y4m" \
        --json "$tmp/g.json" --contact none >/dev/null 2>"$tmp/err" &
    pid=$!
    wait_for_bytes "$tmp/g.y4m" 200000
    child=$(pgrep -P "$pid" | head -n 1)
    [ -n "$child" ] || fail "no renderer process under flythrough $pid"
    kill_at=$(python3 -c 'import os, sys, time
t = time.monotonic(); os.kill(int(sys.argv[1]), 9); print(repr(t))' "$child")
    wait "$pid"; rc=$?
    [ "$rc" -eq 0 ] || fail "exit $rc: $(cat "$tmp/err")"
    [ "$(ffprobe_frames "$tmp/g.y4m")" = 150 ] || fail "ffprobe: not 150 frames"
    python3 - "$tmp/g.json" "$kill_at" <<'PY' || fail "$(cat "$tmp/g.json")"
import json, sys
j, k = json.load(open(sys.argv[1])), float(sys.argv[2])
r = j["renderer_restarts"]
assert len(r) == 1 and "signal 9" in r[0]["cause"], r
r = r[0]
noticed = r["detected_monotonic_s"] - k
to_first = r["first_frame_monotonic_s"] - k
gap = r["gap_ms"] / 1e3
print(f"kill to noticed {noticed * 1e3:.1f} ms, kill to first frame {to_first * 1e3:.1f} ms "
      f"(outside), reported gap {gap * 1e3:.1f} ms, recovery {r['recovery_ms']:.1f} ms")
assert 0.0 <= noticed < 0.05, noticed
assert to_first > noticed
# The last frame rendered before the kill may first be shown by the field after it.
assert gap >= to_first - 1001 / 60000 - 1e-3, (gap, to_first)
assert gap - to_first < 1 / 20 + 1001 / 60000 + 0.02, (gap, to_first)
assert abs(r["recovery_ms"] / 1e3 - (to_first - noticed)) < 0.002, r
PY
    ;;
# A flood of 10,000 good host messages a second over loopback on top of a 60 Hz host: no field
# is missed, every datagram is counted, and no field's poll takes long.
cigi_flood)
    host_flags=(--origin 47,-122,0 --start 300,300,1700 --speed 20)
    "$bin/cigi-host" --port-file "$tmp/port" --seconds 5 --flood 10000 "${host_flags[@]}" \
        --json "$tmp/host.json" 2>"$tmp/host.err" &
    hpid=$!
    wait_for_port "$tmp/port"
    "$fly" --synthetic 128 --cigi 127.0.0.1:0 --cigi-host "127.0.0.1:$(cat "$tmp/port")" \
        --cigi-origin 47,-122 --cigi-wait 10 --duration 3 --out null --contact none \
        --json "$tmp/run.json" "${fly_small[@]}" 2>"$tmp/err" || fail "flythrough: $(cat "$tmp/err")"
    wait "$hpid" || fail "cigi-host: $(cat "$tmp/host.err")"
    python3 - "$tmp/run.json" "$tmp/host.json" <<'PY' || fail "$(cat "$tmp/err" "$tmp/host.err")"
import json, sys
j, h = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
c = j["cigi"]
print("flood:", j["fields"], "fields,", j["missed_deadlines"], "missed,", c["datagrams"],
      "datagrams,", c["dropped_by_kernel"], "dropped, longest poll", round(c["max_poll_ms"], 3), "ms")
assert j["fields"] == 180, j["fields"]
# What the flood costs each field is bounded below (the longest poll). Missed fields on the
# wall clock also come from the machine's own late wake-ups, flood or not (docs/results.md:
# the 10-minute run without a host); so a field or two is allowed here, and the target of 0
# under a flood is measured by scripts/bench-cigi.sh on the results page.
assert j["missed_deadlines"] <= 2, j["missed_deadlines"]
assert h["flood_messages"] >= 40000, h  # 10,000 a second for the whole run at least
assert c["datagrams"] + c["dropped_by_kernel"] >= 25000, c
assert c["bad_datagrams"] == 0, c
assert c["max_poll_ms"] < 8.0, c  # half a field: the flood never costs one
PY
    ;;
# The host falls silent for 1.5 s mid-run: the run goes on, the outage is reported with its
# start and length, the ownship extrapolated for --cigi-extrapolate then held.
cigi_host_silence)
    "$bin/cigi-host" --port-file "$tmp/port" --seconds 4 --silent-from 1 --silent-for 1.5 \
        --origin 47,-122,0 --start 300,300,1700 --speed 20 2>"$tmp/host.err" &
    hpid=$!
    wait_for_port "$tmp/port"
    "$fly" --synthetic 128 --cigi 127.0.0.1:0 --cigi-host "127.0.0.1:$(cat "$tmp/port")" \
        --cigi-origin 47,-122 --cigi-wait 10 --cigi-timeout 0.3 --cigi-extrapolate 0.5 \
        --duration 3.5 --out null --contact none --json "$tmp/run.json" "${fly_small[@]}" \
        2>"$tmp/err" || fail "flythrough: $(cat "$tmp/err")"
    wait "$hpid" || fail "cigi-host: $(cat "$tmp/host.err")"
    grep -q 'cigi: host silent from' "$tmp/err" || fail "outage not reported: $(cat "$tmp/err")"
    python3 - "$tmp/run.json" <<'PY' || fail "$(cat "$tmp/err")"
import json, sys
j = json.load(open(sys.argv[1]))
c = j["cigi"]
assert j["fields"] == 210, j["fields"]
assert c["host_losses"] == 1, c
o = c["host_outages"][0]
assert not o["ongoing"], o
# The host's clock starts when it finds the image generator, before the run's set-up (the
# first frame, the renderer's start): the silence begins up to a few tenths earlier in run time.
assert 0.3 < o["last_message_s"] <= 1.05, o
assert abs(o["length_s"] - 1.5) < 0.15, o
assert abs(o["noticed_s"] - o["last_message_s"] - 0.3) < 0.03, o
# 0.2 s extrapolated (0.5 s after the last message, less the 0.3 s to notice), then held.
assert 8 <= o["fields_extrapolated"] <= 16, o
assert 50 <= o["fields_held"] <= 70, o
PY
    ;;
# Two image generators on one machine (views 0 and 1, ports of their own) driven by one host:
# channels yawed -30 and +30 degrees, 60 degrees wide. The right edge column of the left
# channel's last frame meets the left edge column of the right one's (luma), no worse than
# 1.5 times neighbouring columns beside the edge plus 2 levels (each process warps its own
# frames to the same instants; the unit test CigiView.TwoChannelsMeetAtTheirSharedEdge bounds
# the rendering itself).
cigi_two_channels)
    "$bin/cigi-host" --port-file "$tmp/port" --igs 2 --views 60 --seconds 5 \
        --origin 47,-122,0 --start 300,300,1700 --speed 20 --pitch -40 2>"$tmp/host.err" &
    hpid=$!
    wait_for_port "$tmp/port"
    for view in 0 1; do
        "$fly" --synthetic 128 --cigi 127.0.0.1:0 --cigi-host "127.0.0.1:$(cat "$tmp/port")" \
            --cigi-origin 47,-122 --cigi-wait 10 --cigi-view "$view" --duration 2 \
            --out "y4m:$tmp/v$view.y4m" --contact none --json "$tmp/v$view.json" \
            "${fly_small[@]}" 2>"$tmp/err$view" &
        pids[$view]=$!
    done
    wait "${pids[0]}" || fail "view 0: $(cat "$tmp/err0")"
    wait "${pids[1]}" || fail "view 1: $(cat "$tmp/err1")"
    wait "$hpid" || fail "cigi-host: $(cat "$tmp/host.err")"
    grep -q 'view 1: 60.000 degrees wide' "$tmp/err1" || fail "no View Definition: $(cat "$tmp/err1")"
    python3 - "$tmp" <<'PY' || fail "seam"
import json, sys
tmp = sys.argv[1]
for v in (0, 1):
    j = json.load(open(f"{tmp}/v{v}.json"))
    assert j["fields"] == 120 and j["cigi"]["view"] == v, j
    assert abs(j["fov_deg"] - 60.0) < 1e-6, j["fov_deg"]
w, h = 160, 120
def last_luma(path):
    data = open(path, "rb").read()
    frame = w * h * 2
    body = data[len(data) - frame:]
    return [[body[(y * w + x) * 2 + 1] for x in range(w)] for y in range(h)]
L, R = last_luma(f"{tmp}/v0.y4m"), last_luma(f"{tmp}/v1.y4m")
def diff(a, xa, b, xb):
    return sum(abs(a[y][xa] - b[y][xb]) for y in range(h)) / h
seam = diff(L, w - 1, R, 0)
beside = 0.5 * (diff(L, w - 2, L, w - 1) + diff(R, 0, R, 1))
apart = diff(L, w - 1, R, w - 1)
print(f"seam {seam:.2f}, beside the edge {beside:.2f}, 60 degrees apart {apart:.2f} (luma levels)")
assert seam <= 1.5 * beside + 2.0, (seam, beside)
assert apart > 4.0 * seam, (apart, seam)
PY
    ;;
*)
    fail "unknown case"
    ;;
esac
echo "ok: $case_name"
