#!/usr/bin/env bash
# A probe of a guided policy (analysis/guided_b.py) on seeds no suite uses (seed 9000000): n = 40, 80 x N = 4, 16,
# 25 maps, one repeat. Obstacles (the open grid, iid walls at 0.3, PRIMAL's law, mazes, rooms) against path_greedy
# and walls/b; sharp wrong priors at severity 1 (every family, and the prior right) against B's teacher
# (target-greedy, reach 2), coverage and robust/b (and the evidence switch where coverage wins); the open grid also
# against term/b. Paired comparisons into
# analysis/out/guided_probe/<tag>/<scenario>/vs_<baseline>/; a folder already evaluated is kept (evaluations resume).
# The policy acts through its run's own network (analysis/guided_b.py, imported as an extension).
#   bash analysis/guided_probe.sh [model.zip] [tag]     # defaults: runs/train/guided/walls_b/model.zip, walls_b
#   bash analysis/guided_probe.sh --baselines-only      # the rules and shipped policies alone, while one trains
#   bash analysis/guided_probe.sh runs/train/guided/b_plan/model.zip b_plan
set -euo pipefail
BASELINES_ONLY=
if [ "${1:-}" = --baselines-only ]; then BASELINES_ONLY=1; shift; fi
GUIDED=${1:-runs/train/guided/walls_b/model.zip}
TAG=${2:-walls_b}
P="grid.world_sizes=[40,80] grid.n_targets=[8,16] grid.n_distributions=[16,32] grid.max_agents=[64,128]
   grid.agents=[4,16] grid.maps_per_cell=25 grid.repeats=1 seed=9000000 threads=1 progress_bar=false"
rule() { python -m searchrl.evaluate controller=$1 +model=b $2 $P out_dir=$3 ${4:-}; }
policy() { python -m searchrl.evaluate checkpoint=runs/reference/$1/model.zip $2 $P out_dir=$3; }
probe() {  # probe <scenario name> "<overrides>" <baseline>...
  local s=$1 S=$2 O=runs/eval/guided_probe/$1
  shift 2
  [ -n "$BASELINES_ONLY" ] || python -m searchrl.evaluate extensions=[analysis.guided_b] checkpoint="$GUIDED" $S $P \
      out_dir=$O/$TAG
  for base in "$@"; do
    case $base in
      greedy_target) rule greedy_target "$S" $O/$base controller.reach=2;;
      path_greedy|coverage) rule $base "$S" $O/$base;;
      switch) rule switch "$S" $O/$base controller.threshold=0.25;;
      *) policy ${base/_//} "$S" $O/$base;;  # walls_b -> walls/b, term_b -> term/b, robust_b -> robust/b
    esac
    [ -n "$BASELINES_ONLY" ] || python analysis/compare.py $O/$TAG $O/$base --out analysis/out/guided_probe/$TAG/$s/vs_$base
  done
}
probe paper "scenario=paper" path_greedy walls_b term_b greedy_target
probe walls3 "scenario=walls scenario.obstacles.density=0.3" path_greedy walls_b
probe primal "scenario=primal" path_greedy walls_b
probe maze "scenario=maze" path_greedy walls_b
probe rooms "scenario=rooms" path_greedy walls_b
probe sharp "scenario=sharp" greedy_target coverage robust_b
for f in adversarial flatter misweighted off_prior shifted sharper uninformed; do
  case $f in  # where coverage wins, also the evidence switch: the best rule an agent's own evidence can follow
    adversarial|off_prior|shifted) probe $f "scenario=$f scenario.prior.variance_scale=1.0" greedy_target coverage \
        robust_b switch;;
    *) probe $f "scenario=$f scenario.prior.variance_scale=1.0" greedy_target coverage robust_b;;
  esac
done
