#!/usr/bin/env bash
# Trains the PSB comparison model of docs/EVALUATION.md: the seed's own five Princeton Shape
# Benchmark models per category (its appendix B.1, with the stand-ins named in seed_baseline.sh),
# both codebook types. Academic-use data: the result is for measurements, never shipped.
#   tests/eval/psb_model.sh OUTPUT.ismm [BUILD_DIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
out=${1:?usage: psb_model.sh OUTPUT.ismm [BUILD_DIR]}
build=${2:-$root/build}
psb=$root/../shared/data/cad/psb
[[ -d $psb ]] || { echo "skipped: $psb is absent (development data, see ../shared/docs/DATASETS.md)"; exit 0; }
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
models=(office_chair/m795 office_chair/m796 office_chair/m798 office_chair/m799 office_chair/m801
        dining_chair/m810 dining_chair/m818 dining_chair/m823 dining_chair/m824 dining_chair/m826
        dining_table/m870 dining_table/m872 dining_table/m873 dining_table/m894 dining_table/m874
        couch/m829 couch/m830 couch/m833 couch/m835 couch/m843)
{ printf 'category\tpath\tup\tcredit\n'
  for m in "${models[@]}"; do printf '%s\t%s\ty\tPrinceton Shape Benchmark %s (academic use)\n' "${m%%/*}" "$psb/$m.obj" "${m##*/}"; done
} > "$work/psb.tsv"
exec "$build/core/ism-train" --manifest "$work/psb.tsv" -o "$out" --codebook both
