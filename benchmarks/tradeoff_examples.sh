#!/usr/bin/env bash
# The tradeoff table and Pareto plot of every example garment on a held-out motion (issue 10).
#
#   bash benchmarks/tradeoff_examples.sh [MOTION] [FRAMES] [GARMENT.obj ...]
#
# MOTION: a motion file, default the held-out walk_brisk of the motion library (written to
# data/heldout/ by this script); FRAMES: source frames (60 fps source: 0:60 is one second at 30 fps).
# Models: the shipped one, and when data/models has them the model shipped before it (model_v1.pt, trained on
# data/sim_v1) and the 0/1/2-level variants of benchmarks/train_variants.py (phase 1). One torch thread, so each row's time
# does not depend on what else the machine runs. Results: OUT/<garment>_<motion>/ (OUT from the environment,
# default benchmarks/results/tradeoff), and OUT/summary.md over every scene (benchmarks/tradeoff_summary.py). REUSE_SIM=1 takes the simulator rows from the
# previous run of each scene where nothing they depend on changed, or those an interrupted run finished
# (garment tradeoff --reuse-sim).
set -euo pipefail
cd "$(dirname "$0")/.."
MOTION=${1:-data/heldout/walk_brisk.npz}
FRAMES=${2:-0:60}
OUT=${OUT:-benchmarks/results/tradeoff}
shift $(( $# > 2 ? 2 : $# ))
GARMENTS=("$@")
[ ${#GARMENTS[@]} -gt 0 ] || GARMENTS=(examples/*.obj)
if [ ! -f "$MOTION" ]; then
    mkdir -p "$(dirname "$MOTION")"
    python -c "import sys; from core.motiongen import MOTION_LIBRARY; from formats.motion import save_motion; \
save_motion(sys.argv[1], MOTION_LIBRARY['walk_brisk'](fps=60.0))" "$MOTION"
fi
MODELS=(--model shipped=core/assets/default_model.pt)
# The model shipped before (trained on 10-substep simulations of three lower-body garments), when kept.
[ -f data/models/model_v1.pt ] && MODELS+=(--model "sim_v1 model=data/models/model_v1.pt")
for L in 0 1 2; do
    f=data/models/pool_structure_L${L}_p1.pt
    [ -f "$f" ] && MODELS+=(--model "L${L}-phase1=$f")
done
export OMP_NUM_THREADS=1
for g in "${GARMENTS[@]}"; do
    name=$(basename "$g" .obj)_$(basename "$MOTION" .npz)
    scene=$OUT/$name
    # a finished run's simulations, or those an interrupted run kept
    if [ "${REUSE_SIM:-0}" = 1 ] && { [ -d "$scene/simulations" ] || [ -d "$OUT/.$name.simulations" ]; }; then
        KEEP=--reuse-sim
    else
        KEEP=--overwrite
    fi
    garment tradeoff "$g" "$MOTION" --frames "$FRAMES" "${MODELS[@]}" --repeats 2 \
        --out "$OUT" "$KEEP"
done
python benchmarks/tradeoff_summary.py --results "$OUT"
