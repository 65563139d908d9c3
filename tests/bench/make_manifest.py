#!/usr/bin/env python3
"""Writes the training manifest of the shipped default model into a work folder, as
models/build_default.py does (same catalog entries, sizes, rotations), without touching models/.

    /usr/bin/python3 tests/bench/make_manifest.py --work DIR [--background]   # prints DIR/manifest.tsv

ism-train on it with --background retrains the default model; pcl-ism-peer renders the furniture's
scans from it without.
"""
import argparse
import csv
import importlib.util
import os

HERE = os.path.dirname(os.path.abspath(__file__))
MODELS = os.path.join(HERE, "..", "..", "models")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", required=True, help="folder for the extracted meshes and manifest.tsv")
    ap.add_argument("--furniture-dir", default="/usr/share/sweethome3d/furniture")
    ap.add_argument("--background", action="store_true",
                    help="with the background meshes (default/background.tsv), as the shipped model is trained")
    args = ap.parse_args()

    spec = importlib.util.spec_from_file_location("build_default", os.path.join(MODELS, "build_default.py"))
    build_default = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build_default)

    os.makedirs(args.work, exist_ok=True)
    rows = []
    for table in ["selection.tsv"] + (["background.tsv"] if args.background else []):
        with open(os.path.join(MODELS, "default", table)) as f:
            rows += [r for r in csv.DictReader((l for l in f if not l.startswith("#")), delimiter="\t") if r["role"] == "train"]
    manifest = os.path.join(args.work, "manifest.tsv")
    with open(manifest, "w") as f:
        f.write("category\tpath\twidth_m\tdepth_m\theight_m\tup\trotation\tcredit\n")
        for row in rows:
            m = build_default.extract_entry(args.furniture_dir, row["library"], row["entry"], args.work)
            credit = f'{m["name"]} by {m["creator"]} ({row["library"]} #{row["entry"]}, {m["license"]})'
            f.write("\t".join([row["category"], os.path.relpath(m["obj"], args.work), *(f"{v:.4f}" for v in m["size_m"]),
                               "y", m["rotation"], credit]) + "\n")
    print(manifest)


if __name__ == "__main__":
    main()
