#!/usr/bin/env bash
# The guided policy of research/guided_b_plan (analysis/guided_b.py, an extension) on the frozen suites' own maps
# (their grid and seed: n = 40, 80, 160 x N = 1, 4, 16, 64, 50 maps per cell), beside the rules that lead each
# scenario, then the paired tables (analysis/guided_summary.py). A plain evaluation with a suite's grid, seed and
# scenario plays exactly that scenario's maps, so one scenario can be run alone. Every obstacle scenario; of the
# prior-error suite's 22, the prior right and each family at severity 1. Also the paper's 12 hard cells (100 maps
# each) against term/b. One core; hours; each evaluation resumes where it stopped.
#   bash analysis/guided_suites.sh [all|guided|baselines] [model.zip]   # all (the default): everything, then the
#       tables; guided: only the guided policy's evaluations; baselines: the rest
set -euo pipefail
PART=${1:-all}
GUIDED=${2:-runs/train/guided/b_plan/model.zip}
OUT=runs/eval/guided_suite
SUITE="grid.world_sizes=[40,80,160] grid.n_targets=[8,16,32] grid.n_distributions=[16,32,64] grid.max_agents=[64,128,256]
       grid.agents=[1,4,16,64] grid.maps_per_cell=50 grid.repeats=1 seed=7000000 threads=1 progress_bar=false"
HARD="grid.world_sizes=[40,80,160] grid.n_targets=[8,16,32] grid.n_distributions=[16,32,64] grid.max_agents=[2,8,32]
      grid.maps_per_cell=100 grid.repeats=1 threads=1 progress_bar=false"  # N up to 2, 8, 32: the hard cells
guided() { [ "$PART" = baselines ] || python -m searchrl.evaluate extensions=[analysis.guided_b] \
    checkpoint="$GUIDED" $2 $3 out_dir=$1/b_plan; }
rule() { [ "$PART" = guided ] || python -m searchrl.evaluate +model=b $3 $4 controller=$2 out_dir=$1/$2 ${5:-}; }
term_b() { [ "$PART" = guided ] || python -m searchrl.evaluate checkpoint=runs/reference/term/b/model.zip $2 $3 \
    out_dir=$1/term_b; }
O=$OUT/obstacles  # the suite's scenario labels, in its order
declare -A WALLS=([paper]="scenario=paper" [iid0.1c]="scenario=walls scenario.obstacles.density=0.1"
  [iid0.2c]="scenario=walls" [iid0.3c]="scenario=walls scenario.obstacles.density=0.3" [primal]="scenario=primal"
  [maze3l0.1]="scenario=maze" [rooms12d3]="scenario=rooms")
for s in paper iid0.1c iid0.2c iid0.3c primal maze3l0.1 rooms12d3; do
  guided $O/$s "${WALLS[$s]}" "$SUITE"
  rule $O/$s path_greedy "${WALLS[$s]}" "$SUITE"
done
rule $O/paper greedy_target "scenario=paper" "$SUITE" controller.reach=2  # the best rule on the open grid
term_b $O/paper "scenario=paper" "$SUITE"
guided $OUT/hard/paper "scenario=paper" "$HARD"
term_b $OUT/hard/paper "scenario=paper" "$HARD"
P=$OUT/prior_error
declare -A WRONG=([var1]="scenario=sharp" [var1+adversarial1]="scenario=adversarial" [var1+shifted1]="scenario=shifted"
  [var1+off_prior1]="scenario=off_prior" [var1+tempered1p0]="scenario=flatter" [var1+misweighted1]="scenario=misweighted"
  [var1+tempered1p4]="scenario=sharper" [var1+uninformed1]="scenario=uninformed")
for s in var1+adversarial1 var1+shifted1 var1+off_prior1 var1 var1+tempered1p0 var1+misweighted1 var1+tempered1p4 \
    var1+uninformed1; do
  S="${WRONG[$s]} scenario.prior.variance_scale=1.0"
  guided $P/$s "$S" "$SUITE"
  rule $P/$s greedy_target "$S" "$SUITE" controller.reach=2
  rule $P/$s coverage "$S" "$SUITE"
  rule $P/$s switch "$S" "$SUITE" controller.threshold=0.25
done
[ "$PART" = all ] || exit 0
for s in obstacles prior_error hard; do
  python analysis/guided_summary.py b_plan --probe $OUT/$s --out analysis/out/guided_suite/$s
done
python analysis/compare.py $OUT/hard/paper/b_plan $OUT/hard/paper/term_b --out analysis/out/guided_suite/hard/vs_term_b
