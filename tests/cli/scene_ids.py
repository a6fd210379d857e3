#!/usr/bin/env python3
"""ig-render with a scene: the object-id PNG and the JSON's visible pixel counts and boxes agree,
moving objects move with --time, and the image without the scene's objects is the terrain's.

Usage: scene_ids.py IG_RENDER DATA_DIR TMP_DIR
"""
import json
import os
import struct
import subprocess
import sys
import zlib


def read_png16(path):
    """A 16-bit grey, non-interlaced PNG -> (width, height, rows of ints)."""
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat, w = 8, b"", 0
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert depth == 16 and colour == 0 and interlace == 0, (depth, colour, interlace)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = zlib.decompress(idat)
    stride, bpp = 2 * w, 2
    rows, prev = [], bytearray(stride)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pred) & 255
        rows.append([line[2 * x] << 8 | line[2 * x + 1] for x in range(w)])
        prev = line
    return w, h, rows


def main():
    render, data, tmp = sys.argv[1:4]
    os.makedirs(tmp, exist_ok=True)
    scene = os.path.join(tmp, "scene.json")
    with open(os.path.join(tmp, "lane.csv"), "w") as f:
        f.write("t,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,250,330,0,90,0,0\n10,350,330,0,90,0,0\n")
    models = os.path.join(data, "models")
    json.dump({"cell_m": 1.0,
               "models": {"house": {"vox": os.path.join(models, "house.vox")},
                          "tree": {"vox": os.path.join(models, "conifer.vox")},
                          "tank": {"vox": os.path.join(models, "tank.vox")}},
               "objects": [{"id": 3, "model": "house", "x": 300, "y": 360, "heading": 20},
                           {"id": 9, "model": "tank", "trajectory": "lane.csv", "scale": 0.5}],
               "scatter": [{"model": "tree", "count": 40, "area": [220, 380, 420, 480],
                            "seed": 5, "scale": 0.7}]}, open(scene, "w"))
    runs = {}
    for t in ("0", "10"):
        ids, js = os.path.join(tmp, "ids%s.png" % t), os.path.join(tmp, "objects%s.json" % t)
        subprocess.run([render, "--synthetic", "64:3", "--caster", "reference", "--scene", scene,
                        "--pose", "300,200,+40,0,-12,0", "--size", "160x120", "--time", t,
                        "--out", os.path.join(tmp, "frame.png"), "--objects-out", ids,
                        "--json", js], check=True, stderr=subprocess.DEVNULL)
        w, h, rows = read_png16(ids)
        counted = {}
        for y, row in enumerate(rows):
            for x, v in enumerate(row):
                if v:
                    c = counted.setdefault(v, [0, x, y, x, y])
                    c[0] += 1
                    c[1], c[2] = min(c[1], x), min(c[2], y)
                    c[3], c[4] = max(c[3], x), max(c[4], y)
        reported = {o["id"]: [o["pixels"]] + o["box"] for o in json.load(open(js))["objects"]}
        if counted != reported:
            print("FAIL: the id image and the JSON disagree at t = %s:\n%s\n%s" % (t, counted, reported))
            return 1
        if 3 not in counted or 9 not in counted or len(counted) < 6:
            print("FAIL: expected the house, the tank and trees in view: %s" % sorted(counted))
            return 1
        runs[t] = counted
    # The default (fast) caster draws the same objects: on a single level its terrain is the
    # reference's, so its id image is the reference's pixel for pixel.
    fast_ids = os.path.join(tmp, "ids_fast.png")
    subprocess.run([render, "--synthetic", "64:3", "--levels", "0", "--scene", scene,
                    "--pose", "300,200,+40,0,-12,0", "--size", "160x120", "--time", "0",
                    "--out", os.path.join(tmp, "frame_fast.png"), "--objects-out", fast_ids],
                   check=True, stderr=subprocess.DEVNULL)
    if read_png16(fast_ids) != read_png16(os.path.join(tmp, "ids0.png")):
        print("FAIL: the fast caster's id image differs from the reference's")
        return 1
    # The tank drives 100 m east between the two times: its box moves right.
    if not runs["10"][9][1] > runs["0"][9][3]:
        print("FAIL: the tank did not move: %s -> %s" % (runs["0"][9], runs["10"][9]))
        return 1
    print("ok: %d objects in view; tank box %s -> %s" % (len(runs["0"]), runs["0"][9][1:], runs["10"][9][1:]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
