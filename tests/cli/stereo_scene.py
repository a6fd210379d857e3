#!/usr/bin/env python3
"""ig-render --stereo with a --scene: both eyes' object-id PNGs agree with the JSON's visible
pixel counts, the left eye's ids are the mono frame's, and the right eye's ids are those of a
mono frame rendered from the right eye's pose, but for a small share of object pixels.

Usage: stereo_scene.py IG_RENDER DATA_DIR TMP_DIR
"""
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from scene_ids import read_png16  # noqa: E402


def counts(rows):
    c = {}
    for row in rows:
        for v in row:
            if v:
                c[v] = c.get(v, 0) + 1
    return c


def main():
    render, data, tmp = sys.argv[1:4]
    os.makedirs(tmp, exist_ok=True)
    scene = os.path.join(tmp, "scene.json")
    models = os.path.join(data, "models")
    json.dump({"cell_m": 1.0,
               "models": {"house": {"vox": os.path.join(models, "house.vox")},
                          "tree": {"vox": os.path.join(models, "conifer.vox")}},
               "objects": [{"id": 3, "model": "house", "x": 300, "y": 360, "heading": 20}],
               "scatter": [{"model": "tree", "count": 40, "area": [220, 380, 420, 480],
                            "seed": 5, "scale": 0.7}]}, open(scene, "w"))
    common = [render, "--synthetic", "64:3", "--levels", "0", "--scene", scene,
              "--size", "160x120"]
    t = lambda name: os.path.join(tmp, name)  # noqa: E731
    e = 2.0
    subprocess.run(common + ["--pose", "300,200,+40,0,-12,0", "--stereo", str(e),
                             "--out-left", t("left.png"), "--out-right", t("right.png"),
                             "--objects-out-left", t("ids_left.png"),
                             "--objects-out-right", t("ids_right.png"), "--json", t("pair.json")],
                   check=True, stderr=subprocess.DEVNULL)
    pair = json.load(open(t("pair.json")))
    left, right = read_png16(t("ids_left.png"))[2], read_png16(t("ids_right.png"))[2]
    for name, rows, key in (("left", left, "objects"), ("right", right, "objects_right")):
        reported = {o["id"]: o["pixels"] for o in pair[key]}
        if counts(rows) != reported:
            print("FAIL: the %s eye's id image and the JSON disagree" % name)
            return 1
        if 3 not in reported or len(reported) < 6:
            print("FAIL: expected the house and trees in the %s eye: %s" % (name, sorted(reported)))
            return 1
    # The left eye is the mono frame; the right eye, at yaw 0, is e metres east at the same height.
    z = pair["pose"]["z"]
    for name, x, rows in (("left", 300, left), ("right", 300 + e, right)):
        subprocess.run(common + ["--pose", "%r,200,%r,0,-12,0" % (x, z), "--out", t("mono.png"),
                                 "--objects-out", t("mono_ids.png")],
                       check=True, stderr=subprocess.DEVNULL)
        mono = read_png16(t("mono_ids.png"))[2]
        objects = sum(1 for row in mono for v in row if v)
        differ = sum(1 for a, b in zip(rows, mono) for u, v in zip(a, b) if u != v)
        allowed = 0 if name == "left" else 0.01 * objects
        if differ > allowed:
            print("FAIL: the %s eye's ids differ from the mono frame's on %d of %d object pixels"
                  % (name, differ, objects))
            return 1
        print("ok: %s eye, %d of %d object pixels' ids differ from the mono frame's"
              % (name, differ, objects))
    if counts(left) == counts(right):
        print("FAIL: the eyes see the same object pixels: no parallax")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
