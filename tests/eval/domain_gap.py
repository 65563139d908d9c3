#!/usr/bin/env python3
"""The calibration rooms' peaks beside the real scans' candidates, per category.

The confidence is fitted on rendered rooms (core/training/calibration.h); where the real scans'
peaks look otherwise, it means something else there. This sets the medians of what the
calibration weighs (ln score, supporting keypoints, the verification's fit) side by side, for the
true and the false peaks of each, with their counts.

  ism-train ... --seed 1 --calibration-samples ROOMS.tsv -o MODEL
  ism-eval real -m MODEL ../shared/data/real/sunrgbd ../shared/data/real/scannet --preset default \\
      --min-confidence 0.01 --json REAL.json
  /usr/bin/python3 tests/eval/domain_gap.py ROOMS.tsv REAL.json [--frames] [--draw N]

By default the rooms seen as point samples are compared (the clouds' calibration); --frames takes
the rooms' depth frames (for the Kinect frames' candidates). The rooms' peaks are those whose
confidence reaches --lowest (0.01, below which recognition answers nothing and ism-eval lists no
candidate), so that both sides are the same population. A candidate that was not verified counts
with fit 0.5, as the calibration weighs it.
"""
import argparse
import csv
import json
import math
import statistics


def medians(rows):
    if not rows:
        return "-"
    ln_s = statistics.median(math.log(max(r[0], 1e-12)) for r in rows)
    support = statistics.median(r[1] for r in rows)
    fit = statistics.median(r[2] for r in rows)
    return f"{ln_s:.2f}, {support:.0f}, {fit:.2f} ({len(rows)})"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("samples", help="ism-train --calibration-samples TSV")
    ap.add_argument("real", nargs="+", help="ism-eval real --json output(s)")
    ap.add_argument("--frames", action="store_true", help="the rooms' depth frames, not their point samples")
    ap.add_argument("--draw", type=int, default=0, help="which draw's samples (ism-train --draws)")
    ap.add_argument("--lowest", type=float, default=0.01, help="the rooms' peaks from this confidence up")
    args = ap.parse_args()

    rooms = {}
    with open(args.samples) as f:
        for row in csv.DictReader(f, delimiter="\t"):
            if int(row["draw"]) != args.draw or int(row["cloud"]) == int(args.frames):
                continue
            if not row["confidence"] or float(row["confidence"]) < args.lowest:
                continue
            key = (row["category"], row["positive"] == "1")
            rooms.setdefault(key, []).append((float(row["score"]), int(row["support"]), float(row["fit"])))
    real = {}
    for path in args.real:
        with open(path) as f:
            result = json.load(f)
        for combination in result["combinations"]:
            for c in combination["classes"]:
                for d in c.get("candidates", []):
                    fit = d["fit"] if d["fit"] is not None else 0.5
                    real.setdefault((d["category"], d["tp25"]), []).append((d["score"], d["support"], fit))

    categories = sorted({k[0] for k in rooms} | {k[0] for k in real})
    print("Medians of ln score, supporting keypoints and fit (count):\n")
    print("| category | rooms, true | real, true | rooms, false | real, false | false per true: rooms, real |")
    print("|---|---|---|---|---|---|")
    for category in categories:
        groups = [rooms.get((category, True), []), real.get((category, True), []),
                  rooms.get((category, False), []), real.get((category, False), [])]
        ratio = ", ".join(f"{len(false) / len(true):.0f}" if true else "-"
                          for true, false in ((groups[0], groups[2]), (groups[1], groups[3])))
        print("| " + " | ".join([category] + [medians(g) for g in groups] + [ratio]) + " |")

if __name__ == "__main__":
    main()
