#!/usr/bin/env bash
# CIGI over loopback, on the wall clock: (1) the delay from a host's Entity Control change to the
# first field that applies it: cigi-host (60 Hz, Entity + Rate Control) moves the ownship 50 m
# every 6th host frame and times the step's send to the kernel's arrival stamp (SO_TIMESTAMPNS)
# of the first Start of Frame naming its host frame (sent by the field that applied it, before
# that field is warped), and to when cigi-host read it (its own wake-ups added);
# the field's hand-off follows by the field loop's lateness (slot start to hand-off), taken
# from the same run's stats; (2) the same run with a flood of 10,000 more host messages a
# second; (3) bench-cigi: packets decoded a second and datagrams a session takes a second.
# flythrough runs the shipped map at 720x486 with the renderer process, as in production.
# Writes docs/results/data/cigi_bench.json.
# Usage: scripts/bench-cigi.sh [SECONDS] [OUT_JSON]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-20}"
out="${2:-docs/results/data/cigi_bench.json}"
bin=build/release/bin
for p in flythrough cigi-host bench-cigi; do
    [ -x "$bin/$p" ] || { echo "bench-cigi: build $p first (cmake --build --preset release)" >&2; exit 1; }
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

run() {  # run NAME FLOOD_PER_SECOND
    local name="$1" flood="$2"
    rm -f "$tmp/port"
    "$bin/cigi-host" --port-file "$tmp/port" --seconds "$((seconds + 3))" --steps 6 \
        --flood "$flood" --origin 47,-122,0 --start 114339,62347,2600 --heading 40 \
        --pitch -3 --speed 160 --json "$tmp/$name.host.json" 2>"$tmp/$name.host.err" &
    local hpid=$!
    for _ in $(seq 300); do [ -s "$tmp/port" ] && break; sleep 0.1; done
    "$bin/flythrough" --cigi 127.0.0.1:0 --cigi-host "127.0.0.1:$(cat "$tmp/port")" \
        --cigi-origin 47,-122 --cigi-wait 10 --duration "$seconds" --out null --contact none \
        --quiet --json "$tmp/$name.fly.json" 2>"$tmp/$name.fly.err"
    wait "$hpid"
    cat "$tmp/$name.host.err" >&2
}

run steady 0
run flood 10000
"$bin/bench-cigi" --benchmark_repetitions=5 --benchmark_out="$tmp/bench.json" \
    --benchmark_out_format=json >/dev/null

python3 - "$tmp" "$seconds" "$out" <<'PY'
import json, os, platform, statistics, sys
tmp, seconds, out = sys.argv[1], float(sys.argv[2]), sys.argv[3]
runs = {}
for name in ("steady", "flood"):
    host = json.load(open(f"{tmp}/{name}.host.json"))
    fly = json.load(open(f"{tmp}/{name}.fly.json"))
    host.pop("samples_ms", None)
    runs[name] = {"host": host, "fields": fly["fields"],
                  "missed_deadlines": fly["missed_deadlines"],
                  "lateness_ms": fly["field_lateness_ms"] if "field_lateness_ms" in fly else fly.get("lateness_ms"),
                  "render_fps": fly["render_fps"], "cigi": fly["cigi"]}
bench = json.load(open(f"{tmp}/bench.json"))
def per_second(name):
    return [b["items_per_second"] for b in bench["benchmarks"]
            if b["run_name"] == name and b.get("run_type") == "iteration"]
doc = {"what": "CIGI over loopback: host message to field, flood, decoding",
       "seconds": seconds, "cores": os.cpu_count(),
       "machine": platform.processor() or platform.machine(),
       "command": "scripts/bench-cigi.sh " + sys.argv[2],
       "field_period_ms": 1001.0 / 60.0,
       "runs": runs,
       "decode_packets_per_second": per_second("BM_DecodeHostMessage"),
       "session_datagrams_per_second": per_second("BM_SessionPollFlood")}
os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
json.dump(doc, open(out, "w"), indent=1)
for name, r in runs.items():
    d = r["host"]["step_to_field_ms"]
    rd = r["host"].get("step_to_field_read_ms", {})
    print(f"{name:7} step to field p50 {d['p50']:.2f} p99 {d['p99']:.2f} max {d['max']:.2f} ms "
          f"(read p50 {rd.get('p50', float('nan')):.2f} p99 {rd.get('p99', float('nan')):.2f}) "
          f"({r['host']['steps_seen']} steps); lateness {r['lateness_ms']}; "
          f"missed {r['missed_deadlines']} of {r['fields']}; datagrams {r['cigi']['datagrams']}, "
          f"longest poll {r['cigi']['max_poll_ms']:.2f} ms, "
          f"{r['cigi'].get('max_poll_datagrams', '?')} datagrams at most in one")
print("decode: %.1f M packets/s; session: %.0f k datagrams/s" % (
    statistics.median(doc["decode_packets_per_second"]) / 1e6,
    statistics.median(doc["session_datagrams_per_second"]) / 1e3))
PY
