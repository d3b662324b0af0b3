#!/usr/bin/env bash
# Add to ./.whl the wheels QDax's MAP-Elites needs on the offline GPU machine (which already has
# jax, flax, optax, chex and their deps: numpy>=2, scipy>=1.14, absl-py, typing_extensions).
# Run from the project root:  bash scripts/qdax_wheels.sh [--no-sklearn]
# Then install on the GPU machine as the header of ../shared/tools/gpu-wheels.sh shows
# (pip install --no-index --no-deps --target /tmp/site .whl/*.whl; PYTHONPATH=/tmp/site:$PWD).
#
# qdax 0.5.0 is installed without its declared deps (brax, jumanji, tensorflow-probability,
# jinja2 are not imported by qdax.core.map_elites, the MAP-Elites repertoire, the standard
# emitters, mutation_operators or qdax.utils.metrics). The only heavy import on that path is
# `from sklearn.cluster import KMeans` at the top of qdax/core/containers/mapelites_repertoire.py
# (used only by compute_cvt_centroids); importing sklearn needs joblib (-> cloudpickle),
# threadpoolctl and narwhals. Together about 10 MB; scipy comes with jax on the GPU machine.
# --no-sklearn adds only qdax (0.3 MB): the caller must then put a stub `sklearn.cluster.KMeans`
# into sys.modules before importing qdax (fine as long as compute_cvt_centroids is not used).
set -euo pipefail
root=$(git rev-parse --show-toplevel)
cd "$root"
pkgs=(qdax==0.5.0 scikit-learn==1.9.1 joblib==1.6.0 cloudpickle==3.1.3 threadpoolctl==3.8.0
      narwhals==2.29.0)
names=(qdax scikit_learn joblib cloudpickle threadpoolctl narwhals)
if [ "${1:-}" = --no-sklearn ]; then pkgs=(qdax==0.5.0); names=(qdax); fi
bash ../shared/tools/gpu-wheels.sh "${pkgs[@]}"
files=()
for n in "${names[@]}"; do
  f=$(ls .whl/"$n"-*.whl 2>/dev/null | head -1) || true
  [ -n "$f" ] || { echo "missing wheel: $n" >&2; exit 1; }
  files+=("$f")
done
echo "QDax wheels: $(du -cb "${files[@]}" | awk 'END {printf "%.1f MiB", $1 / 1048576}');" \
  "all of .whl: $(du -sb .whl | awk '{printf "%.1f MiB", $1 / 1048576}')"
