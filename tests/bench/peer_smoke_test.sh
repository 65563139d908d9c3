#!/usr/bin/env bash
# Smoke test of the bench tools, not a timing: pcl-ism-peer trains PCL's ISM on two scans and
# compares it with ours on one scene. Two procedural meshes (a table and a chair made of boxes),
# one view each; the shipped sample scene. Passes when the peer exits 0 and writes JSON with
# every field run.sh's report reads, numbers where numbers are expected.
#   peer_smoke_test.sh PEER_BINARY MODEL.ismm SCENE.json
set -euo pipefail
peer=$1 model=$2 scene=$3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

/usr/bin/python3 - "$work" <<'PY'
import os, sys
work = sys.argv[1]
def boxes(name, parts):  # closed axis-aligned boxes, z up
    with open(os.path.join(work, name + ".obj"), "w") as f:
        for i, (x0, y0, z0, x1, y1, z1) in enumerate(parts):
            for x, y, z in [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
                            (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]:
                f.write(f"v {x} {y} {z}\n")
            for q in [(1, 2, 3, 4), (5, 8, 7, 6), (1, 5, 6, 2), (2, 6, 7, 3), (3, 7, 8, 4), (4, 8, 5, 1)]:
                f.write("f " + " ".join(str(8 * i + v) for v in q) + "\n")
legs = lambda w, d, h, t: [(x, y, 0, x + t, y + t, h) for x in (-w, w - t) for y in (-d, d - t)]
boxes("table", [(-0.6, -0.4, 0.70, 0.6, 0.4, 0.75)] + legs(0.6, 0.4, 0.70, 0.05))
boxes("chair", [(-0.22, -0.22, 0.42, 0.22, 0.22, 0.46), (-0.22, 0.18, 0.46, 0.22, 0.22, 0.90)] + legs(0.22, 0.22, 0.42, 0.04))
with open(os.path.join(work, "manifest.tsv"), "w") as f:
    f.write("category\tpath\tup\ndining_table\ttable.obj\tz\ndining_chair\tchair.obj\tz\n")
PY

"$peer" --manifest "$work/manifest.tsv" --model "$model" --views 1 --ours-repeats 1 --json "$work/out.json" "$scene"

/usr/bin/python3 - "$work/out.json" <<'PY'
import json, math, sys
out = json.load(open(sys.argv[1]))
def number(v, what):
    assert isinstance(v, (int, float)) and math.isfinite(v), f"{what} is {v!r}, not a finite number"
assert out["training"]["scans"] == 2, out["training"]
assert out["training"]["words"] > 0, out["training"]
assert len(out["scenes"]) == 1, out["scenes"]
scene = out["scenes"][0]
number(scene["ours"]["ms"], "our time")
assert "error" not in scene["pcl"], scene["pcl"]
number(scene["pcl"]["ms"], "PCL's time")
for key in ("ours", "pcl_all_peaks", "pcl_top_peak"):
    s = out["summary"][key]
    number(s["rate"], key + " rate")
    assert 0 <= s["rate"] <= 1 and s["objects"] == 3 and s["tp"] + s["fn"] == 3, (key, s)
number(out["summary"]["ours_median_ms"], "our median")
number(out["summary"]["pcl_median_ms"], "PCL's median")
print("smoke test passed: rates ours", out["summary"]["ours"]["rate"], "PCL", out["summary"]["pcl_all_peaks"]["rate"])
PY
