#!/usr/bin/env bash
# The seed's synthetic baseline (seed_baseline.sh) with the default preset over several draws of
# training's randomness, for the two rules that size meshes without a size (PSB's): the category's
# typical height alone (--unsized-by-height, the seed preset's rule) and the best fit of the box
# to its typical width, depth and height (the default). The table of docs/EVALUATION.md.
#   tests/eval/seed_baseline_draws.sh [BUILD_DIR] OUTPUT.md [-- SEED...]
# Draws: the untouched default ("-") and seeds 1-4, unless given. About 80 s per run on 2 cores.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build}
out=${2:?usage: $0 BUILD_DIR OUTPUT.md [-- SEED...]}
shift 2
[[ ${1:-} == -- ]] && shift
draws=("$@")
((${#draws[@]})) || draws=(- 1 2 3 4)
[[ -d $root/../shared/data/cad/psb ]] || { echo "skipped: ../shared/data/cad/psb is absent"; exit 0; }
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT

for draw in "${draws[@]}"; do
  seed=(); [[ $draw == - ]] || seed=(--seed "$draw")
  for rule in height box; do
    flag=(); [[ $rule == height ]] && flag=(--unsized-by-height)
    "$root/tests/eval/seed_baseline.sh" "$build" "${seed[@]}" "${flag[@]}" --json "$work/$rule.$draw.json" \
      > /dev/null 2> "$work/$rule.$draw.log"
    echo "baseline draws: $rule $draw done" >&2
  done
done

/usr/bin/python3 - "$work" "${draws[@]}" > "$out" <<'PY'
import json
import statistics
import sys
work, draws = sys.argv[1], sys.argv[2:]


def cells(rule, draw):
    doc = json.load(open(f"{work}/{rule}.{draw}.json"))
    c = next(c for c in doc["combinations"] if c["strategy"] == "global 1nn+lw")
    t = c["confusion"]
    counts = {r: dict(zip(t["cols"], row)) for r, row in zip(t["rows"], t["counts"])}
    wrong = sum(n for r in t["rows"] for col, n in counts[r].items() if col not in (r, "none"))
    none = sum(counts[r]["none"] for r in t["rows"])
    diagonal = " / ".join(str(counts[r][r]) for r in t["rows"])
    return 100 * c["accuracy"], diagonal, wrong, none, t["rows"]


rows = {(rule, d): cells(rule, d) for rule in ("height", "box") for d in draws}
categories = rows[("box", draws[0])][4]
print("Global 1nn+lw at the default min_confidence, 96 test scans; right per category (" + " / ".join(categories) +
      "), called another category, answered nothing.\n")
print("| draw | typical height: accuracy | right | wrong | none | typical box: accuracy | right | wrong | none |")
print("|---|---|---|---|---|---|---|---|---|")
for d in draws:
    h, b = rows[("height", d)], rows[("box", d)]
    name = "untouched" if d == "-" else f"--seed {d}"
    print(f"| {name} | {h[0]:.1f} % | {h[1]} | {h[2]} | {h[3]} | {b[0]:.1f} % | {b[1]} | {b[2]} | {b[3]} |")
mean = {rule: statistics.mean(rows[(rule, d)][0] for d in draws) for rule in ("height", "box")}
print(f"| mean | {mean['height']:.1f} % | | | | {mean['box']:.1f} % | | | |")
PY
cat "$out"
