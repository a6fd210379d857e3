#!/usr/bin/env bash
# Wireshark's CIGI dissector reads what our codec writes: every packet of the sample host and
# image generator messages, big- and little-endian, is decoded with no malformed packet or
# expert note, with the values we wrote, and the same values in both byte orders.
# Usage: cigi_tshark.sh CIGI_PCAP_PROGRAM WORK_DIR      (exit 77: skipped, no tshark)
set -u
program="$1"; work="$2"
if ! command -v tshark >/dev/null; then
    echo "SKIP: tshark is not installed (Debian package tshark; scripts/setup.sh installs it)"
    exit 77
fi
pcap="$work/cigi_samples.pcap"
"$program" "$pcap" || { echo "FAIL: $program could not write $pcap"; exit 1; }
fail=0
# The dissector takes the version (3.3) and the byte order from IG Control / Start of Frame.
decode=(tshark -n -r "$pcap" -d udp.port==8004,cigi)
text=$("${decode[@]}" -V 2>/dev/null) || { echo "FAIL: tshark could not read $pcap"; exit 1; }
expert=$("${decode[@]}" -q -z expert 2>/dev/null)

if grep -qi "malformed" <<<"$text"; then echo "FAIL: tshark reports a malformed packet"; fail=1; fi
if grep -Eq "^(Errors|Warnings|Notes) " <<<"$expert"; then
    echo "FAIL: tshark expert information:"; echo "$expert"; fail=1
fi
packets=$(grep -c "Packet ID:" <<<"$text")
if [ "$packets" -ne 36 ]; then echo "FAIL: $packets CIGI packets decoded, expected 36"; fail=1; fi

expect() {  # a line tshark must print, and how many times (both byte orders)
    local count; count=$(grep -cF -- "$1" <<<"$text")
    if [ "$count" -ne "$2" ]; then echo "FAIL: '$1' printed $count times, expected $2"; fail=1; fi
}
# The size byte of every packet (the dissector itself reads fixed layouts).
expect "Packet Size (bytes): 24" 8
expect "Packet Size (bytes): 48" 6
expect "Packet Size (bytes): 32" 10
expect "Packet Size (bytes): 64" 2
expect "Packet Size (bytes): 56" 4
expect "Packet Size (bytes): 16" 4
expect "Packet Size (bytes): 40" 2
expect "Minor Version: 3" 4
expect "Byte Swap: Big-Endian (0x8000)" 2
expect "Byte Swap: Little-Endian (0x0080)" 2
expect "Database Number: -5" 2
expect "Host Frame Number: 123456" 2
expect "Entity ID: 4660" 10
expect "Ground/Ocean Clamp: Conformal (2)" 2
expect "Animation State: Continue (3)" 4
expect "Linear Extrapolation/Interpolation Enable: Enabled" 4
expect "Attach State: Attach" 2
expect "Latitude (degrees)/X Offset (m): 47.6062" 2
expect "Longitude (degrees)/Y Offset (m): -122.3321" 2
expect "Yaw (degrees): 271.5" 4
expect "Coordinate System: Local" 2
expect "Yaw Angular Rate (degrees/s): 1.75" 2
expect "Yaw (degrees): 359.5" 2
expect "Mirror Mode: Vertical (2)" 2
expect "Pixel Replication Mode: 2x2 (3)" 2
expect "View Type: 5" 2
expect "Far (m): 50000" 2
expect "Request Type: Extended (2)" 2
expect "Longitude (degrees)/Y Offset (m): 151.2" 2
expect "Material Mask: 3735928559" 2
expect "Destination Entity ID: 4661" 2
expect "Maximum Range (m): 20000" 2
expect "IG Mode: Debug (2)" 2
expect "Earth Reference Model: Host-Defined" 2
expect "IG Frame Number: 4000000000" 2
expect "Response Type: HOT" 2
expect "Host Frame Number LSN: 15" 2
expect "HAT: 2876.625" 2
expect "Normal Vector Elevation (degrees): 80.5" 2
expect "Range (m): 15000.5" 2
expect "Range (m): 812.25" 2
expect "Blue: 30" 2
expect "Track Mode: Target (3)" 2
expect "Polarity: Black hot" 2
expect "Line-by-Line Dropout Enable: Disabled" 2
expect "Track White/Black: Black" 2
expect "Response Type: Extended" 2
expect "Gain: 0.75" 2
expect "AC Coupling (microseconds): 2.5" 2
expect "Component Class: Sensor (3)" 2
expect "Component State: 2" 2
# The dissector prints the component data words as raw bytes; the standard (and the CIGI Class
# Library) swaps them as 32-bit words, so the little-endian frame shows them reversed.
expect "Component Data 1: 00001235" 1
expect "Component Data 1: 35120000" 1
expect "Component Data 6: cafef00d" 1
expect "Sensor Status: Tracking target (1)" 2
expect "Sensor Status: Breaklock (3)" 2
expect "Entity ID: 4661" 8
expect "Gate X Position (degrees): -3.25" 2
expect "Gate Y Position (degrees): -6.5" 2
expect "Gate Y Size (pixels or raster lines): 30" 2
expect "Frame Counter: 3000000000" 2
expect "Track Point Longitude (degrees): -122.375" 2
expect "Track Point Altitude (m): 450.5" 2

# Frames 1 and 3 (host) and 2 and 4 (image generator) differ only in byte order.
cigi() {  # the CIGI part of one frame, byte-swap line removed
    "${decode[@]}" -V -Y "frame.number == $1" 2>/dev/null |
        sed -n '/^Common Image Generator Interface/,$p' | grep -v "Byte Swap:\|Component Data" |
        tail -n +2
}
for pair in "1 3" "2 4"; do
    set -- $pair
    if ! diff <(cigi "$1") <(cigi "$2") >/dev/null; then
        echo "FAIL: frames $1 and $2 decode differently:"; diff <(cigi "$1") <(cigi "$2") | head -20
        fail=1
    fi
done
if [ "$fail" -eq 0 ]; then
    echo "ok: tshark $(tshark --version 2>/dev/null | head -1 | awk '{print $3}') decodes $packets CIGI 3.3 packets as written"
fi
exit "$fail"
