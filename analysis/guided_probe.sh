#!/usr/bin/env bash
# A small probe of the guided policy (analysis/guided_b.py) against path_greedy and walls/b: n = 40, 80 x N = 4, 16,
# 25 maps, one repeat, on the open grid, iid walls at 0.3 (connected), PRIMAL's law, mazes and rooms; paired
# comparisons into analysis/out/guided_probe/<scenario>/vs_<baseline>/.
#   bash analysis/guided_probe.sh [runs/train/guided/walls_b/model.zip]
set -euo pipefail
GUIDED=${1:-runs/train/guided/walls_b/model.zip}
P="grid.world_sizes=[40,80] grid.n_targets=[8,16] grid.n_distributions=[16,32] grid.max_agents=[64,128]
   grid.agents=[4,16] grid.maps_per_cell=25 grid.repeats=1 threads=1 progress_bar=false"
for s in paper walls3 primal maze rooms; do
  case $s in paper) S="scenario=paper";; walls3) S="scenario=walls scenario.obstacles.density=0.3";; *) S="scenario=$s";; esac
  O=runs/eval/guided_probe/$s
  python -m searchrl.evaluate controller=path_greedy +model=b $S $P out_dir=$O/path_greedy
  python -m searchrl.evaluate checkpoint=runs/reference/walls/b/model.zip $S $P out_dir=$O/walls_b
  python analysis/guided_b.py evaluate checkpoint="$GUIDED" $S $P out_dir=$O/guided
  for base in path_greedy walls_b; do
    python analysis/compare.py $O/guided $O/$base --out analysis/out/guided_probe/$s/vs_$base
  done
done
