#!/bin/sh
# /init of the device-test VM (scripts/device-tests.sh): loads vivid and the simulated GPIO
# chip, runs the checks, prints "VIG-RESULT: N passed, M failed" on the console, powers off.
/bin/busybox --install -s /bin
export PATH=/vig:/bin HOME=/tmp
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev
mount -t debugfs debugfs /sys/kernel/debug
mount -t tmpfs tmpfs /tmp
cd /tmp || exit 1
echo VIG-BEGIN
passed=0
failed=0
check() {  # check NAME COMMAND...: runs it, its output indented, counts the verdict
    name=$1
    shift
    echo "== $name"
    if "$@" >/tmp/out 2>&1; then
        passed=$((passed + 1))
        sed 's/^/   /' /tmp/out | tail -"${VIG_TAIL:-15}"
        echo "PASS $name"
    else
        failed=$((failed + 1))
        sed 's/^/   /' /tmp/out | tail -60
        echo "FAIL $name"
    fi
}

# vivid: one instance with a video capture node (bit 0) and a video output node (bit 8). Its
# default crop/compose/scale settings let the output take NTSC's 486 lines (243 a field); with
# ccs_out_mode=0 it answers 480, but its loop-back then no longer returns the lines sent.
while read -r ko; do
    case "$ko" in
        */vivid.ko) insmod "$ko" n_devs=1 node_types=0x101 ;;
        *) insmod "$ko" ;;
    esac
done </vig/modules
insmod /vig/vig_gpio_sim.ko lines=8
for d in /dev/video*; do
    caps=$(v4l2-ctl -d "$d" --info 2>/dev/null | sed -n '/Device Caps/,$p')
    case "$caps" in
        *"Video Output"*) out=$d ;;
        *"Video Capture"*) cap=$d ;;
    esac
done
gpio=/sys/kernel/debug/vig-gpio-sim/pull
echo "vivid capture $cap, output $out; $(uname -r)"

# Loop-back: capture input 2 (S-Video) and output 0 (S-Video), both NTSC, no text overlay.
v4l2-ctl -d "$cap" --set-input 2 >/dev/null && v4l2-ctl -d "$cap" --set-standard ntsc >/dev/null &&
    v4l2-ctl -d "$out" --set-output 0 >/dev/null && v4l2-ctl -d "$out" --set-standard ntsc >/dev/null &&
    v4l2-ctl -d "$cap" -c loop_video=1 -c osd_text_mode=2 || echo "vivid loop-back setup failed"
v4l2-ctl -d "$cap" --get-input --get-standard --get-fmt-video -C loop_video

# v4l2-compliance on the output node, as it is before the product touches it. v4l-utils 1.22
# expects other format descriptions than kernel 6.1 gives ('Y/UV 4:2:0' for 'Y/CbCr 4:2:0'):
# those failures are the tool's age, not the driver's; any other failure counts.
compliance() {
    v4l2-compliance -d "$out" -s 10 >/tmp/compliance 2>&1
    grep '^Total' /tmp/compliance
    grep 'fail:' /tmp/compliance | sort | uniq -c
    grep 'fail:' /tmp/compliance | grep -vq 'fmtdesc.description mismatch' && return 1
    grep -q '^Total.*Succeeded' /tmp/compliance
}
check "v4l2-compliance $out (streaming, mmap)" compliance

# The same GoogleTest code paths as everywhere, now against the real drivers.
export VIG_V4L2_OUTPUT="$out" VIG_V4L2_CAPTURE="$cap" VIG_GPIO_CHIP=vig-gpio-sim VIG_GPIO_PULL="$gpio"
VIG_TAIL=30 check "io_tests against vivid and vig-gpio-sim" io_tests --gtest_brief=0 \
    --gtest_filter='V4l2Sink.Real*:GpiodChipPort.RealLibrary:GpioStick.RealChip*'
if grep -q SKIPPED /tmp/out; then
    echo "FAIL a real-device test skipped inside the VM"
    failed=$((failed + 1))
fi

# io-check: the moving test pattern to the output on the wall clock, two seconds. Under an
# emulated CPU deadlines are missed (exit 3); every field must still reach the device.
pattern_check() {
    io-check pattern --out "v4l2:$out" --duration 2
    [ $? -le 3 ] && grep -q "120 of 120 fields" /tmp/out && grep -q "sink errors 0" /tmp/out
}
check "io-check pattern --out v4l2:$out" pattern_check

# io-check stick on the simulated chip while a shell presses "up" with chatter, then "right".
stick_check() {
    for o in 0 1 2 3 4 5 6; do echo "$o 0" >$gpio; done
    io-check stick gpiod:vig-gpio-sim:0,1,2,3,4,5,6 --duration 3 --rate 20 >/tmp/stick &
    pid=$!
    sleep 1.2
    echo "0 1" >$gpio; echo "0 0" >$gpio; echo "0 1" >$gpio
    sleep 0.6
    echo "0 0" >$gpio; echo "3 1" >$gpio
    wait $pid || return 1
    cat /tmp/stick
    grep -q 'pitch +1.00  roll +0.00' /tmp/stick && grep -q 'pitch +0.00  roll +1.00' /tmp/stick &&
        head -1 /tmp/stick | grep -q 'pitch +0.00  roll +0.00'
}
VIG_TAIL=30 check "io-check stick gpiod:vig-gpio-sim" stick_check

if [ -x /vig/flythrough ]; then
    check "flythrough --out v4l2:$out" flythrough --synthetic 256 --contact none --quiet --out "v4l2:$out" --duration 1 --renderer thread
fi

# The stick reaches the pose the PRP warps each field to without waiting for the renderer: after
# an edge on the simulated chip, the first field whose stick sample has the line pressed already
# shows it in its pose (the flight-path angle climbs there, level before), no field logged before
# the edge was made saw it, and the press counts at most two fields after the field that read the
# edge from the chip (the 10 ms debounce is less than a field; one more for a field that starts
# late). Field indices from --field-log, no timings.
stick_pose_check() {
    for o in 0 1 2 3 4 5 6; do echo "$o 0" >$gpio; done
    log=/tmp/fields.jsonl
    rm -f $log
    flythrough --synthetic 256 --size 32x24 --margin 4 --renderer thread --render-threads 1 \
        --contact none --quiet --out null --duration 3 \
        --stick gpiod:vig-gpio-sim:0,1,2,3,4,5,6 --field-log $log &
    pid=$!
    before=0
    while [ "$before" -lt 40 ] && kill -0 $pid 2>/dev/null; do
        sleep 0.02
        before=$(cat $log 2>/dev/null | wc -l)
    done
    echo "0 1" >$gpio
    wait $pid || return 1
    echo "edge made after $before fields were logged"
    awk -v before="$before" '
        function num(text, key) {
            if (!match(text, "\"" key "\":-?[0-9.e+-]+")) return -1
            return substr(text, RSTART + length(key) + 3, RLENGTH - length(key) - 3) + 0
        }
        {
            n = num($0, "field"); pitch[n] = num($0, "pitch_deg"); frame[n] = num($0, "frame")
            if (!match($0, "\"stick\":[{][^}]*[}]")) { print "no stick in field " n; bad = 1 }
            stick = substr($0, RSTART, RLENGTH)
            edges[n] = num(stick, "edges"); pressed[n] = num(stick, "pitch") > 0.5
            if (edges[n] > 0 && readAt == "") readAt = n
            if (pressed[n] && first == "") first = n
            last = n
        }
        END {
            if (bad) exit 1
            if (readAt == "" || first == "") { print "the edge never reached the stick"; exit 1 }
            for (k = first - 3; k <= first + 1; ++k)
                if (k >= 0 && k <= last)
                    printf "field %d  edges %d  pressed %d  pitch %.5f deg  frame %d\n", k, edges[k], pressed[k], pitch[k], frame[k]
            if (readAt < before || first < before) { print "a field logged before the edge saw it"; exit 1 }
            if (first > readAt + 2) { print "field " readAt " read the edge, the press counted only at field " first; exit 1 }
            if (first < 2 || pitch[first - 1] != pitch[first - 2]) { print "not level before the press"; exit 1 }
            if (!(pitch[first] > pitch[first - 1] + 1e-3)) { print "the pose of field " first " does not show the press"; exit 1 }
            print "field " readAt " read the edge; the pose climbs from field " first ", the first to sample the press"
        }' $log
}
VIG_TAIL=12 check "flythrough --stick gpiod: an edge shows in the next field's pose" stick_pose_check

echo "VIG-RESULT: $passed passed, $failed failed"
echo VIG-END
poweroff -f
