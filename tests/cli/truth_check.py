#!/usr/bin/env python3
"""flythrough --scene --truth over the village (naive caster, simulated clock): one JSON line per
field, fields and times in order, the tank in view and its box near its true box, and the same
file from the renderer process and the renderer thread.

Usage: truth_check.py FLYTHROUGH DATA_DIR TMP_DIR
"""
import json
import math
import os
import subprocess
import sys

FIELD = 1001.0 / 60000.0


def run(fly, data, out, renderer):
    subprocess.run([fly, "--scene", os.path.join(data, "scenes", "puget-sound.json"),
                    "--trajectory", os.path.join(data, "scenes", "village-pass.csv"),
                    "--caster", "naive", "--size", "160x108", "--fov", "50", "--format", "rgb8",
                    "--clock", "simulated", "--duration", "0.5", "--renderer", renderer,
                    "--out", "null", "--contact", "none", "--quiet", "--truth", out],
                   check=True, stdout=subprocess.DEVNULL)
    return open(out, encoding="utf-8").read()


def main():
    fly, data, tmp = sys.argv[1:4]
    os.makedirs(tmp, exist_ok=True)
    a = run(fly, data, os.path.join(tmp, "process.jsonl"), "process")
    b = run(fly, data, os.path.join(tmp, "thread.jsonl"), "thread")
    assert a == b, "the renderer process and thread give different truth"
    lines = a.splitlines()
    assert len(lines) == 30, len(lines)
    tank_seen = 0
    for n, line in enumerate(lines):
        j = json.loads(line)
        assert j["field"] == n, (n, j["field"])
        assert abs(j["time"] - n * FIELD) < 1e-5, (n, j["time"])
        ids = [o["id"] for o in j["objects"]]
        assert ids == sorted(set(ids)), ids
        for o in j["objects"]:
            for key in ("visible_px", "bbox", "centroid", "range_m", "occluded", "true_bbox",
                        "unoccluded_px", "moving"):
                assert key in o, (key, o)
            assert o["range_m"] > 0
            if o["visible_px"] > 0:
                x0, y0, x1, y1 = o["bbox"]
                assert 0 <= x0 < x1 <= 160 and 0 <= y0 < y1 <= 108, o
                cx, cy = o["centroid"]
                assert x0 <= cx <= x1 and y0 <= cy <= y1, o
            if o["occluded"] is not None:
                assert 0.0 <= o["occluded"] <= 1.0, o
        tank = [o for o in j["objects"] if o["id"] == 8]
        if tank and tank[0]["visible_px"] >= 4:
            t = tank[0]
            assert t["moving"], t
            # Within a few pixels of its exact box: the box's own motion over a frame's age,
            # the pixel grid, the object grid's resampling.
            err = max(abs(p - q) for p, q in zip(t["bbox"], t["true_bbox"]))
            assert err <= 4.0, t
            tank_seen += 1
    assert tank_seen >= 20, f"the tank is visible in {tank_seen} of 30 fields"
    print(f"ok: 30 fields, the tank in {tank_seen}")


if __name__ == "__main__":
    main()
