#!/usr/bin/env bash
# The calibration study of k (docs/world.md, "Which k"): heuristics on the full Table 2 grid, 100 maps × 1 repeat,
# in four worlds: λk = 1 (world=bayes) and k = n/2, n (world=paper), 2n. About 40 min on one core.
# Results: runs/eval/calibration/<world>/<controller>/; then `python analysis/calibration.py`.
set -euo pipefail
cd "$(dirname "$0")/.."
declare -A WORLDS=(
  [bayes]="world=bayes"
  [k0.5n]="env.world.k=0 env.world.k_per_n=0.5"
  [paper]="world=paper"
  [k2n]="env.world.k=0 env.world.k_per_n=2"
)
declare -A CONTROLLERS=(
  [surfing]="controller=surfing"
  [coverage]="controller=coverage"
  [random]="controller=random"
  [greedy]="controller=greedy"
  [greedy_target]="controller=greedy_target"  # recorded as greedy with horizon=3 w_p=0 w_u=0 w_t=1
)
for world in bayes paper k0.5n k2n; do
  for controller in surfing coverage random greedy greedy_target; do
    # shellcheck disable=SC2086  # the settings are lists of overrides
    python -m searchrl.evaluate ${CONTROLLERS[$controller]} ${WORLDS[$world]} grid.repeats=1 threads=1 \
      progress_bar=false out_dir="runs/eval/calibration/$world/$controller" "$@"
  done
done
