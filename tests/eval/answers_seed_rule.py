#!/usr/bin/env python3
"""What the service answers at its default operating point on the development scans, scored by
the seed's rule: ism-detect --json (default options, clouds with --up 0,0,1) on the Kinect frames,
the sample scene and the SUN RGB-D and ScanNet clouds, each answer right when its category's class
matches an object's not yet found and the centroid of its supporting keypoints lies within a
quarter of that object's longest edge of its centre, as ../shared/tools/score_detect.py scores one
frame. ism-eval real recognises down to confidence 0.01 and counts the answers above the threshold;
this runs recognition at the threshold itself, as a client does.

    /usr/bin/python3 tests/eval/answers_seed_rule.py --bin build/core -m MODEL [--out DIR] [--objects] [--cloud-up X,Y,Z]
        [-- ISM-DETECT OPTIONS]

Prints r = TP / (objects + FP) per class with (TP, FP), and false answers per scan. With
--objects, first a line per object (its scan, class and size; its class's most confident answer
right by the seed's rule, and the most confident one whose box centre lies within half the
object's longest edge, "-" for none; the most confident answer of any class there) and a line per
false answer (its nearest object, how far its box centre and its support centroid lie from it):
with `-- --min-confidence 0.01`, where the candidates of each object stand. Only the Python
standard library is used.
"""
import argparse
import glob
import json
import math
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
REAL = os.path.join(ROOT, "..", "shared", "data", "real")
CLASS = {"office_chair": "chair", "dining_chair": "chair", "chair": "chair", "dining_table": "table|desk",
         "table": "table|desk", "desk": "table|desk", "couch": "sofa", "sofa": "sofa"}


def scenes(cloud_up="0,0,1"):
    frames = [os.path.join(REAL, "kinect", n) for n in ("tum_desk", "office1")]
    frames.append(os.path.join(ROOT, "models", "sample", "living_room"))
    clouds = sorted(p[:-4] for d in ("sunrgbd", "scannet") for p in glob.glob(os.path.join(REAL, d, "*.pcd")))
    return [(f, []) for f in frames] + [(c, ["--up", cloud_up]) for c in clouds]


def right_by_rule(h, o):
    """The seed's rule: the answer's class is the object's, its support centroid within a quarter of
    the object's longest edge of its centre."""
    return CLASS[h["category"]] == CLASS[o["category"]] and \
        math.dist(h["support_centroid"], o["center"]) < max(o["size"]) / 4


CLASSES = ("chair", "table|desk", "sofa")


def tally(totals, objects, answers):
    """Adds one scan to `totals` (per class: true answers, false answers, objects), its answers
    matched greedily in their order by the seed's rule, each object found once; returns the false
    answers."""
    for o in objects:
        totals[CLASS[o["category"]]][2] += 1
    found = [False] * len(objects)
    false = []
    for h in answers:
        cls = CLASS[h["category"]]
        hit = next((i for i, o in enumerate(objects) if not found[i] and right_by_rule(h, o)), None)
        if hit is None:
            totals[cls][1] += 1
            false.append(h)
        else:
            found[hit] = True
            totals[cls][0] += 1
    return false


def r_text(tp, fp, objects):
    """r = TP / (objects + FP) in per cent, with the true and false answers."""
    return f"{100 * tp / (objects + fp):.1f} ({tp}, {fp})"


def conf(h):
    return "-" if h is None else f"{h['category']} {h['confidence']:.2f}"


def size(o):
    return "x".join(f"{v:.2f}" for v in o["size"])


def list_objects(scan, objects, answers):
    """Each object's most confident answers: of its class by the seed's rule, of its class by box
    centre, of any class by box centre."""
    for o in objects:
        cls, reach = CLASS[o["category"]], max(o["size"])
        near = [h for h in answers if math.dist(h["center"], o["center"]) < reach / 2]
        rule = [h for h in answers if right_by_rule(h, o)]
        best = lambda hs: max(hs, key=lambda h: h["confidence"], default=None)
        print(f"object {scan} {cls} size {size(o)}: rule {conf(best(rule))}"
              f" | box {conf(best([h for h in near if CLASS[h['category']] == cls]))} | any {conf(best(near))}")


def list_false(scan, h, objects):
    """A false answer, beside its nearest object."""
    o = min(objects, key=lambda o: math.dist(o["center"], h["center"]), default=None)
    where = "no object" if o is None else (
        f"nearest {o['category']} size {size(o)} box centre "
        f"{math.dist(o['center'], h['center']):.2f} m, support centroid {math.dist(o['center'], h['support_centroid']):.2f} m")
    print(f"false {scan} {conf(h)}: {where}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", required=True, help="folder holding ism-detect")
    ap.add_argument("-m", "--model", required=True)
    ap.add_argument("--out", help="keep each scene's ism-detect --json here")
    ap.add_argument("--objects", action="store_true", help="list each object's best answers and each false answer")
    ap.add_argument("--cloud-up", default="0,0,1",
                    help="the up the clouds are sent with (their frames' z; another to see what a slightly tilted up moves)")
    ap.add_argument("detect_options", nargs="*", help="after --: more ism-detect options")
    args = ap.parse_args()
    if not os.path.isdir(REAL):
        sys.exit(f"no development scans at {REAL} (../shared/docs/DATASETS.md)")
    out = args.out or tempfile.mkdtemp(prefix="answers_")
    os.makedirs(out, exist_ok=True)

    def detect(scene):
        stem, extra = scene
        path = os.path.join(out, os.path.basename(stem) + ".json")
        with open(path, "w") as f:
            subprocess.run([os.path.join(args.bin, "ism-detect"), "-m", args.model, "--json", *extra,
                            *args.detect_options, stem + ".pcd"], check=True, stdout=f, stderr=subprocess.DEVNULL)
        return stem, path

    totals = {c: [0, 0, 0] for c in CLASSES}  # TP, FP, objects
    count = 0
    with ThreadPoolExecutor(max_workers=2) as pool:
        for stem, path in pool.map(detect, scenes(args.cloud_up)):
            count += 1
            with open(stem + ".json") as f:
                objects = [o for o in json.load(f)["objects"] if o["category"] in CLASS]
            with open(path) as f:
                answers = json.load(f)[0]["hypotheses"]
            false = tally(totals, objects, answers)
            if args.objects:
                for h in false:
                    list_false(os.path.basename(stem), h, objects)
                list_objects(os.path.basename(stem), objects, answers)
    print("  ".join(f"{c} r {r_text(*counts)}" for c, counts in totals.items()),
          f" false answers per scan {sum(v[1] for v in totals.values()) / count:.2f} ({count} scans)")


if __name__ == "__main__":
    main()
