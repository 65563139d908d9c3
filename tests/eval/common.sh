# Sourced by the scripts that train models from the shipped recipe and measure them on the
# development scans (ablation.sh, seeds.sh). Needs $root (the checkout) and $build (a build folder).
# Exits 0 with a note when ../shared/data/real is absent; otherwise sets
#   real                 the development scans
#   manifest             the shipped model's 21 furniture meshes
#   background_manifest  the same with the 21 background meshes (models/default/background.tsv)
real=$root/../shared/data/real
[[ -d $real ]] || { echo "skipped: $real is absent (development data, see ../shared/docs/DATASETS.md)"; exit 0; }
manifest=$(/usr/bin/python3 "$root/models/build_default.py" --bin "$build/core" --work "$build/default-model-src" \
           --no-background --manifest-only)
background_manifest=$(/usr/bin/python3 "$root/models/build_default.py" --bin "$build/core" \
                      --work "$build/background-model-src" --manifest-only)
