#!/usr/bin/env python3
"""How far the seed's r could rise by moving the operating point or by calibrating the confidence
on real scans instead of rendered rooms, with the answers as they are: an upper bound for any
change that only rescales confidences. Reads the answers of every development scan down to
confidence 0.01, as answers_seed_rule.py keeps them:

    /usr/bin/python3 tests/eval/answers_seed_rule.py --bin build/core -m MODEL --out DIR -- --min-confidence 0.01
    /usr/bin/python3 tests/eval/recalibration_bound.py DIR

Prints r = TP / (objects + FP) per class by the seed's rule (answers_seed_rule.right_by_rule,
matched greedily by descending confidence) for:
1. the confidence as recognition gives it, cut at several thresholds: the best of them is chosen
   on the very scans it is scored on, so it is optimistic;
2. each category's confidence made again by a logistic regression over the calibration's inputs
   (ln s, ln s per supporting keypoint, the verification's fit and profile distance), fitted on
   the other rooms' answers (leave one room out: ScanNet's rescans of one room go together);
3. the confidence itself recalibrated the same way (Platt: a slope and an intercept on its logit).
Each answer carries the features of the draw that answered it (its support merged over the peaks
of its object), while its confidence is the mean of the draws'. Needs numpy (python3-numpy).
"""
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from answers_seed_rule import CLASS, CLASSES, r_text, right_by_rule, scenes, tally  # noqa: E402


def load(folder):
    """Per scan: its room, its objects of the three classes, its answers."""
    data = {}
    for stem, _ in scenes():
        scan = os.path.basename(stem)
        with open(stem + ".json") as f:
            objects = [o for o in json.load(f)["objects"] if o["category"] in CLASS]
        with open(os.path.join(folder, scan + ".json")) as f:
            answers = json.load(f)[0]["hypotheses"]
        data[scan] = (scan[:9] if scan.startswith("scene") else scan, objects, answers)
    return data


def r_at(data, confidence, threshold):
    """r per class, (TP, FP), of the answers whose confidence(scan, index, answer) reaches threshold."""
    totals = {c: [0, 0, 0] for c in CLASSES}
    for scan, (_, objects, answers) in data.items():
        ranked = sorted(((confidence(scan, i, h), h) for i, h in enumerate(answers)), key=lambda t: -t[0])
        tally(totals, objects, [h for c, h in ranked if c >= threshold])
    return " | ".join(r_text(*counts) for counts in totals.values())


def logistic(X, y, l2):
    """Newton's method for an L2-penalised logistic regression (the last column, the intercept, unpenalised)."""
    w = np.zeros(X.shape[1])
    penalty = l2 * np.r_[np.ones(X.shape[1] - 1), 0.0]
    for _ in range(100):
        p = 1 / (1 + np.exp(-X @ w))
        g = X.T @ (p - y) + penalty * w
        H = X.T @ (X * (p * (1 - p))[:, None]) + np.diag(penalty + 1e-9)
        step = np.linalg.solve(H, g)
        w -= step
        if np.abs(step).max() < 1e-9:
            break
    return w


def calibration_inputs(h):
    v = h.get("verification") or {}
    s, n = max(h["score"], 1e-6), max(h["support"], 1)
    return [math.log(s), math.log(s / n), v.get("fit", 0.5), v.get("profile_distance", 0.5), 1.0]


def confidence_logit(h):
    p = min(max(h["confidence"], 1e-4), 1 - 1e-4)
    return [math.log(p / (1 - p)), 1.0]


def leave_one_room_out(data, inputs, l2):
    """Per (scan, answer index): its category's regression fitted on the other rooms' answers."""
    # Each answer's row once: its room, category, inputs and whether it is right by the seed's rule.
    rows = [(room, h["category"], (scan, i), np.array(inputs(h)), any(right_by_rule(h, o) for o in objects))
            for scan, (room, objects, answers) in data.items() for i, h in enumerate(answers)]
    made = {}
    for category in sorted({r[1] for r in rows}):
        own = [r for r in rows if r[1] == category]
        for held in sorted({r[0] for r in rows}):
            train = [r for r in own if r[0] != held]
            y = np.array([1.0 if r[4] else 0.0 for r in train])
            w = logistic(np.array([r[3] for r in train]), y, l2) if train and y.sum() > 0 else None
            for room, _, key, x, _ in own:
                if room == held:
                    made[key] = 0.0 if w is None else float(1 / (1 + np.exp(-x @ w)))
    return made


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    data = load(sys.argv[1])
    print("| confidence | threshold | chair r (TP, FP) | table or desk r | sofa r |")
    print("|---|---|---|---|---|")
    for t in (0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5):
        print(f"| as recognised | {t} | {r_at(data, lambda s, i, h: h['confidence'], t)} |")
    for name, inputs, l2 in (("calibration's inputs refitted on the other rooms", calibration_inputs, 1.0),
                             ("recalibrated on the other rooms (Platt)", confidence_logit, 0.1)):
        made = leave_one_room_out(data, inputs, l2)
        for t in (0.2, 0.25, 0.3):
            print(f"| {name} | {t} | {r_at(data, lambda s, i, h: made[(s, i)], t)} |")


if __name__ == "__main__":
    main()
