#!/usr/bin/env python3
"""ig-render --poses with a --scene: each frame's colour PNG, depth PFM, object-id PNG and the
JSON's per-object pixel counts and boxes equal a single call at that frame's pose and time
(--time + k * --time-step), with 1 and 3 threads; a trajectory CSV's frames are at its times.

Usage: render_batch_scene.py IG_RENDER DATA_DIR TMP_DIR
"""
import filecmp
import json
import os
import subprocess
import sys


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
    poses = ["300,200,+40,0,-12,0", "290,210,+45,5,-10,0", "310,190,+35,-5,-14,0",
             "300,220,+50,2,-16,0", "280,200,+40,10,-11,0"]
    with open(os.path.join(tmp, "poses.txt"), "w") as f:
        f.write("# x,y,z,yaw,pitch,roll\n" + "\n".join(poses) + "\n")
    common = [render, "--synthetic", "64:3", "--scene", scene, "--size", "120x90",
              "--haze", "400", "--sun", "200,30"]
    start, step = 1.0, 2.0
    for threads in ("1", "3"):
        b = os.path.join(tmp, "b" + threads)
        subprocess.run(common + ["--poses", os.path.join(tmp, "poses.txt"), "--time", str(start),
                                 "--time-step", str(step), "--threads", threads,
                                 "--out", b + "_c#.png", "--depth", b + "_d#.pfm",
                                 "--objects-out", b + "_i#.png", "--json", b + ".json"],
                       check=True, stderr=subprocess.DEVNULL)
    batch = json.load(open(os.path.join(tmp, "b1.json")))
    if len(batch["frames"]) != len(poses):
        print("FAIL: %d frame records, expected %d" % (len(batch["frames"]), len(poses)))
        return 1
    moved = set()
    for k, pose in enumerate(poses):
        t = start + k * step
        s = os.path.join(tmp, "s%d" % k)
        subprocess.run(common + ["--pose", pose, "--time", repr(t), "--out", s + "_c.png",
                                 "--depth", s + "_d.pfm", "--objects-out", s + "_i.png",
                                 "--json", s + ".json"], check=True, stderr=subprocess.DEVNULL)
        for kind, ext in (("c", "png"), ("d", "pfm"), ("i", "png")):
            single = "%s_%s.%s" % (s, kind, ext)
            for threads in ("1", "3"):
                numbered = os.path.join(tmp, "b%s_%s%d.%s" % (threads, kind, k, ext))
                if not filecmp.cmp(single, numbered, shallow=False):
                    print("FAIL: frame %d %s, %s threads: batch differs from the single call"
                          % (k, kind, threads))
                    return 1
        record = batch["frames"][k]
        single = json.load(open(s + ".json"))["objects"]
        if record["time"] != t or record["objects"] != single:
            print("FAIL: frame %d JSON: time %s objects %s, single call %s %s"
                  % (k, record["time"], record["objects"], t, single))
            return 1
        if not any(o["id"] == 9 for o in single) or not any(o["id"] == 3 for o in single):
            print("FAIL: frame %d: expected the house and the tank in view: %s" % (k, single))
            return 1
        moved.add(tuple(next(o["box"] for o in single if o["id"] == 9)))
    if len(moved) < 2:
        print("FAIL: the tank's box did not change over the batch's times")
        return 1
    # A trajectory CSV: frames at its sample times, the objects stamped at each.
    traj = os.path.join(tmp, "cam.csv")
    with open(traj, "w") as f:
        f.write("t,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,300,200,300,0,-12,0\n4,300,220,300,0,-12,0\n")
    subprocess.run(common + ["--poses", traj, "--every", "2", "--out",
                             os.path.join(tmp, "t#.png"), "--json", os.path.join(tmp, "t.json")],
                   check=True, stderr=subprocess.DEVNULL)
    times = [r["time"] for r in json.load(open(os.path.join(tmp, "t.json")))["frames"]]
    if times != [0.0, 2.0, 4.0]:
        print("FAIL: trajectory frame times %s, expected [0, 2, 4]" % times)
        return 1
    print("ok: %d frames with objects equal to single calls (1 and 3 threads)" % len(poses))
    return 0


if __name__ == "__main__":
    sys.exit(main())
