"""The figures of one model's tests/eval/real_eval.sh run, as docs/EVALUATION.md's tables show them.

Imported by the table scripts; `real_row.py PREFIX` prints one model's figures."""
import json
import math
import sys


def classes(path):
    return {c["class"]: c for c in json.load(open(path))["combinations"][0]["classes"]}


# The classes the issues' targets name; a model's further categories (a bed) are left out of the
# means, so that rows of models with and without them compare.
CLASSES = ("chair", "table|desk", "sofa")


def map25(cs):
    """The mean AP@0.25 over CLASSES that have objects (None: none has)."""
    aps = [cs[c]["ap25"] for c in CLASSES if cs[c]["objects"] > 0 and cs[c]["ap25"] is not None]
    return sum(aps) / len(aps) if aps else None


def fp_per_scan(cs):
    """False answers of CLASSES per scan."""
    return sum(cs[c]["fp"] for c in CLASSES) / max(c["scenes"] for c in cs.values())


def figures(prefix):
    """mAP@0.25 of the frames and of the clouds, the clouds' chair / table / sofa AP@0.25, chair r and
    false positives per scan at 0.5 (fractions), all over CLASSES."""
    everything = classes(f"{prefix}.all.json")
    org, unorg = classes(f"{prefix}.organized.json"), classes(f"{prefix}.unorganized.json")
    return {
        "frames": map25(org),
        "clouds": map25(unorg),
        "per_class": [unorg[c]["ap25"] for c in CLASSES],
        "chair_r": everything["chair"]["rate"],
        "fp_per_scan": fp_per_scan(everything),
    }


def pct(v):
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{100 * v:.1f}"


if __name__ == "__main__":
    f = figures(sys.argv[1])
    print(f"frames {pct(f['frames'])} clouds {pct(f['clouds'])} [{' / '.join(pct(v) for v in f['per_class'])}] "
          f"chair r {pct(f['chair_r'])} FP/scan {f['fp_per_scan']:.2f}")
