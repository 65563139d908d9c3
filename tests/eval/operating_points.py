"""Recall and false positives at other operating points than the default min_confidence, from
tests/eval/real_eval.sh's JSON: what a user choosing --min-confidence trades.

    /usr/bin/python3 tests/eval/operating_points.py PREFIX... [--at 0.5,0.4,0.3,0.2]

For each PREFIX (PREFIX.all.json, every development scan) and threshold t, per class of
real_row.CLASSES: the candidates at confidence t or more that match a true box at 3D IoU 0.25
(TP) and those that do not (FP), r = TP / (objects + FP), and all classes' FP per scan. IoU 0.25
is AP@0.25's match, not ism-eval's centre rule, so r at 0.5 here differs from its column in the
tables a little. Prints one markdown table per PREFIX."""
import argparse
import json

from real_row import CLASSES


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("prefixes", nargs="+")
    ap.add_argument("--at", default="0.5,0.4,0.3,0.25,0.2", help="thresholds, comma separated")
    args = ap.parse_args()
    thresholds = [float(t) for t in args.at.split(",")]
    for prefix in args.prefixes:
        data = json.load(open(f"{prefix}.all.json"))
        classes = {c["class"]: c for c in data["combinations"][0]["classes"]}
        scenes = max(c["scenes"] for c in classes.values())
        print(f"{prefix}:\n")
        print("| min_confidence | " + " | ".join(f"{c.replace('|', ' or ')} r (TP / objects, FP)" for c in CLASSES) + " | FP per scan |")
        print("|---" * (len(CLASSES) + 2) + "|")
        for t in thresholds:
            cells, fps = [], 0
            for name in CLASSES:
                c = classes[name]
                tp = sum(1 for confidence, right in c["confidence_tp25"] if confidence >= t and right)
                fp = sum(1 for confidence, right in c["confidence_tp25"] if confidence >= t and not right)
                fps += fp
                cells.append(f"{100 * tp / (c['objects'] + fp):.1f} ({tp} / {c['objects']}, {fp})")
            print(f"| {t:g} | " + " | ".join(cells) + f" | {fps / scenes:.2f} |")
        print()


if __name__ == "__main__":
    main()
