#!/usr/bin/env python3
"""flythrough --stereo with a --scene: the objects appear in both eyes (the fields differ from the
same flight without the scene in the left and the right half of the side-by-side output), and
the renderer as a thread and as a process give the same video.

Usage: fly_stereo_scene.py FLYTHROUGH DATA_DIR TMP_DIR
"""
import os
import subprocess
import sys


def run(fly, data, out, renderer, scene):
    args = [fly, "--trajectory", os.path.join(data, "scenes", "village-pass.csv"),
            "--size", "160x108", "--fov", "50", "--format", "rgb8", "--clock", "simulated",
            "--duration", "0.5", "--renderer", renderer, "--stereo", "1",
            "--out", "y4m:" + out, "--contact", "none", "--quiet"]
    if scene:
        args += ["--scene", os.path.join(data, "scenes", "puget-sound.json")]
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return open(out, "rb").read()


def luma_planes(video):
    """Y4M -> (width, height, [luma plane bytes per frame])."""
    header, _, rest = video.partition(b"\n")
    fields = header.split()
    w = int(next(f[1:] for f in fields if f.startswith(b"W")))
    h = int(next(f[1:] for f in fields if f.startswith(b"H")))
    colour = next((f[1:] for f in fields if f.startswith(b"C")), b"420")
    size = w * h * {b"444": 3, b"422": 2, b"mono": 1}.get(colour[:4], 1.5)
    size = int(size)
    frames, pos = [], 0
    while pos < len(rest):
        assert rest.startswith(b"FRAME", pos), pos
        pos = rest.index(b"\n", pos) + 1
        frames.append(rest[pos:pos + w * h])
        pos += size
    return w, h, frames


def main():
    fly, data, tmp = sys.argv[1:4]
    os.makedirs(tmp, exist_ok=True)
    thread = run(fly, data, os.path.join(tmp, "thread.y4m"), "thread", True)
    process = run(fly, data, os.path.join(tmp, "process.y4m"), "process", True)
    bare = run(fly, data, os.path.join(tmp, "bare.y4m"), "thread", False)
    if thread != process:
        print("FAIL: the thread and process renderers' stereo videos differ")
        return 1
    w, h, with_objects = luma_planes(thread)
    _, _, without = luma_planes(bare)
    if len(with_objects) != len(without) or not with_objects:
        print("FAIL: %d fields with the scene, %d without" % (len(with_objects), len(without)))
        return 1
    half = w // 2
    differ = [0, 0]
    for a, b in zip(with_objects, without):
        for y in range(h):
            row_a, row_b = a[y * w:(y + 1) * w], b[y * w:(y + 1) * w]
            differ[0] += sum(1 for x in range(half) if row_a[x] != row_b[x])
            differ[1] += sum(1 for x in range(half, w) if row_a[x] != row_b[x])
    if min(differ) < 100:
        print("FAIL: the objects are missing from an eye: %d left, %d right pixels differ" %
              tuple(differ))
        return 1
    ratio = differ[1] / differ[0]
    if not 0.5 < ratio < 2.0:
        print("FAIL: the eyes show the objects on very different areas: %d left, %d right" %
              tuple(differ))
        return 1
    print("ok: %d fields; object pixels (luma differs from the bare flight) left %d, right %d"
          % (len(with_objects), differ[0], differ[1]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
