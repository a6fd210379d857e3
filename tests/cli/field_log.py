#!/usr/bin/env python3
"""flythrough --field-log: one JSON line per field, in order, with the pose each field is warped
to and the stick sampled for it. A scripted stick pulls up at 0.5 s (simulated clock): the first
field whose stick sample is pulled up already shows it in its pose, level before.

usage: field_log.py FLYTHROUGH WORKDIR
"""
import json
import os
import subprocess
import sys

fly, work = sys.argv[1], sys.argv[2]
os.makedirs(work, exist_ok=True)
script = os.path.join(work, "pull_up.stick")
log = os.path.join(work, "fields.jsonl")
with open(script, "w", encoding="utf-8") as f:
    f.write("0.5 axis pitch 1\n")
subprocess.run([fly, "--synthetic", "256", "--size", "64x48", "--clock", "simulated",
                "--renderer", "thread", "--duration", "1", "--out", "null", "--contact", "none",
                "--quiet", "--stick", "script:" + script, "--field-log", log], check=True)
fields = [json.loads(line) for line in open(log, encoding="utf-8")]


def fail(why):
    sys.exit(f"field_log.py: {log}: {why}")


if [f["field"] for f in fields] != list(range(len(fields))) or len(fields) < 50:
    fail(f"expected fields 0, 1, 2 ... (about 60), got {len(fields)} lines")
if any(b["time_s"] <= a["time_s"] for a, b in zip(fields, fields[1:])):
    fail("field times do not increase")
pressed = [f["field"] for f in fields if f["stick"]["pitch"] > 0.5]
if not pressed:
    fail("the stick never pulled up")
first = pressed[0]
if pressed != list(range(first, len(fields))) or not 0.45 < fields[first]["time_s"] < 0.55:
    fail(f"pulled up from field {first} at {fields[first]['time_s']} s, expected from 0.5 s on")
pitch = [f["pose"]["pitch_deg"] for f in fields]
if any(p != pitch[0] for p in pitch[:first]):
    fail("the pose was not level before the stick pulled up")
if not pitch[first] > pitch[first - 1] + 1e-3:
    fail(f"field {first} sampled the pull-up but its pose does not show it")
print(f"field_log.py: the pose climbs from field {first}, the first to sample the pull-up")
