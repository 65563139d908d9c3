#!/usr/bin/env python3
"""Renders tables with chairs drawn up to them, seen past the chairs' backs, for ism-eval.

    /usr/bin/python3 tests/eval/tables_behind_chairs.py --bin build/core OUT_DIR
    build/core/ism-eval real -m models/default/furniture.ismm OUT_DIR --json OUT.json
    /usr/bin/python3 tests/eval/tables_behind_chairs.py --score OUT.json

A chair's back in front of a table hides a swath of the table's top from the sensor, as in the
sample scene and in tum_desk: the top is measured in pieces. The scenes hold meshes of
sweethome3d-furniture that neither the shipped model nor the sample scene uses, so what they
measure is how recognition boxes a table it has not seen, not its memory of one. The layouts are
drawn from a fixed seed: the same scenes every run. --score prints, per class, how many objects
some answer overlaps by 3D IoU 0.25 and 0.5 and their mean best IoU (ism-eval's
objects_outcome). Only the Python standard library is used.
"""
import argparse
import json
import os
import random
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "models"))
import build_default  # noqa: E402  (the catalogue's extraction, shared with the shipped model's build)

# Held out of models/default/selection.tsv: (library, entry).
TABLES = [("BlendSwap-CC-0", 134), ("KatorLegaz", 52), ("Scopia", 39), ("Scopia", 93), ("Scopia", 67),
          ("BlendSwap-CC-0", 48)]
CHAIRS = [("BlendSwap-CC-0", 26), ("BlendSwap-CC-0", 101), ("BlendSwap-CC-0", 108), ("BlendSwap-CC-BY", 24),
          ("BlendSwap-CC-BY", 128), ("Scopia", 29), ("Scopia", 62)]
LAYOUTS_PER_TABLE = 2


def rotation(mesh):
    """The catalogue's modelRotation (nine numbers, row-major) as ism-scene's spec takes it."""
    return {"rotation": [float(v) for v in mesh["rotation"].split()]} if mesh["rotation"] else {}


def render(args):
    work = os.path.join(args.out, "meshes")  # the meshes and the scenes' specs: ism-eval reads OUT_DIR's *.json
    os.makedirs(work, exist_ok=True)
    entry = lambda lib, e: build_default.extract_entry(args.furniture_dir, lib, e, work)
    tables = [entry(*t) for t in TABLES]
    chairs = [entry(*c) for c in CHAIRS]
    rng = random.Random(11)
    n = 0
    for table in tables:
        w, d, h = table["size_m"]
        front = -d / 2
        for _ in range(LAYOUTS_PER_TABLE):
            objects = [{"category": "dining_table", "mesh": table["obj"], "size": [w, d, h], "x": 0.0, "y": 0.0,
                        "yaw": 0.0, "up": "y", **rotation(table)}]
            credits = [table]
            # One chair per 0.8 m of the table's front, up to two, drawn up to it with its back to the sensor.
            count = 1 if w < 1.6 else 2
            for i in range(count):
                chair = rng.choice(chairs)
                cw, cd, ch = chair["size_m"]
                x = (i + 0.5) / count * w - w / 2 + rng.uniform(-0.1, 0.1)
                y = front - cd / 2 + rng.uniform(0.0, 0.15)
                objects.append({"category": "dining_chair", "mesh": chair["obj"], "size": [cw, cd, ch], "x": x,
                                "y": y, "yaw": 0.0, "up": "y", **rotation(chair)})
                credits.append(chair)
            eye = [rng.uniform(-0.8, 0.8), front - rng.uniform(2.0, 2.8), rng.uniform(1.0, 1.6)]
            spec = {"objects": objects, "camera": {"eye": eye, "target": [0.0, 0.0, 0.5]}, "seed": 100 + n,
                    "source": "ism-scene virtual Kinect render of Sweet Home 3D meshes: " + "; ".join(
                        f'{m["name"]} by {m["creator"]} ({m["license"]})' for m in credits),
                    "license": "the meshes' (sweethome3d-furniture)"}
            name = f"tables_{n:02d}"
            with open(os.path.join(work, name + ".spec.json"), "w") as f:
                json.dump(spec, f, indent=1)
            subprocess.run([os.path.join(args.bin, "ism-scene"), "--spec", os.path.join(work, name + ".spec.json"),
                            "--out", os.path.join(args.out, name)],
                           check=True, stdout=subprocess.DEVNULL)
            n += 1
    print(f"{n} scenes in {args.out}")


def score(path):
    with open(path) as f:
        result = json.load(f)
    for k in result["combinations"][0]["classes"]:
        outcomes = k["objects_outcome"]
        if not outcomes:
            continue
        found = [o["best_iou"] for o in outcomes if o["best_iou"] >= 0.25]
        mean = sum(found) / len(found) if found else float("nan")
        print(f'{k["class"]:12s} objects {len(outcomes):3d}  IoU >= 0.25: {len(found):3d}  '
              f'>= 0.5: {sum(1 for v in found if v >= 0.5):3d}  mean best IoU of those: {mean:.3f}  '
              f'AP@0.25 {100 * k["ap25"]:.1f}')


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", nargs="?", help="folder to write the scenes to")
    ap.add_argument("--bin", help="folder holding ism-scene")
    ap.add_argument("--furniture-dir", default="/usr/share/sweethome3d/furniture")
    ap.add_argument("--score", metavar="EVAL_JSON", help="print the boxes' overlaps from an ism-eval --json output")
    args = ap.parse_args()
    if args.score:
        score(args.score)
    elif args.out and args.bin:
        render(args)
    else:
        ap.error("give OUT_DIR and --bin, or --score EVAL_JSON")


if __name__ == "__main__":
    main()
