#!/usr/bin/env bash
# Generates the standard phantoms of this folder with their default parameters (see phantoms/README.md).
# Usage: phantoms/generate.sh MAGVINE_BINARY [OUT_DIR]   (OUT_DIR defaults to this folder)
# Deterministic: the same binary writes bit-identical files, so the meshes are not kept in git; the ground-truth
# graphs and metadata committed here are what this script writes.
set -euo pipefail
magvine=${1:?usage: generate.sh MAGVINE_BINARY [OUT_DIR]}
out=${2:-$(dirname "$0")}
mkdir -p "$out"
"$magvine" phantom bronchial_tree --out "$out/bronchial_tree.stl"
"$magvine" phantom bronchial_tree --flow-ratio 0.4 --max-generation 5 --out "$out/bronchial_tree_asymmetric.stl"
"$magvine" phantom tube --out "$out/tube.stl"
"$magvine" phantom y_bifurcation --out "$out/y_bifurcation.stl"
"$magvine" phantom s_bend --out "$out/s_bend.stl"
for gap in 2 3 5; do
  "$magvine" phantom constriction --gap-mm "$gap" --out "$out/constriction_${gap}mm.stl"
done
