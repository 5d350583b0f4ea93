#!/usr/bin/env bash
# The figures of docs/performance.md#machines that need a GPU machine, measured in one run (under ten minutes on one
# H100/H200 with 16 cores), most needed first: B's recipe's throughput and the shares of its wall time at
# machine=gpu, a whole full-grid evaluation of term/b on the GPU from a new bound cache, which starts from the
# shipped bounds (runs/reference/bounds: no bound of the grid's maps is computed; timed end to end, at most 300 s),
# the world at 1 and 16 threads, a profile of one n = 160 cell of that evaluation, its bounds computed (where a
# cell's time goes on the GPU), then the paper's `+model=c` at machine=gpu for the time left (its progress.csv comes back: its
# rate, and its end if it gets there).
#   bash analysis/device_check.sh            # results under $OUT (the device tool's folder) or runs/device/
#   BUDGET=580 bash analysis/device_check.sh # seconds the whole script may take (the +model=c run gets the rest)
set -uo pipefail
OUT=${OUT:-runs/device}
BUDGET=${BUDGET:-580}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
LOG="$OUT/log.txt"
JSON="$OUT/bench.jsonl"
T0=$(date +%s)
say() { echo "== $(date +%T) +$(( $(date +%s) - T0 ))s $*" | tee -a "$LOG"; }

say "machine"
{ nvidia-smi --query-gpu=name,memory.total --format=csv,noheader; nproc; git rev-parse --short HEAD 2>/dev/null
  python -c "import torch, numba, numpy; print('torch', torch.__version__, 'numba', numba.__version__, \
'numpy', numpy.__version__, 'cuda', torch.cuda.is_available())"; } 2>&1 | tee -a "$LOG"

say "bench train: B's recipe, machine=gpu"
timeout 150 python -m searchrl.bench train --experiment term/b --machine gpu --updates 3 --json 2>>"$LOG" \
    | tee -a "$JSON"

say "evaluate: term/b on the full grid, device=cuda threads=16, a new bound cache (the shipped bounds)"
start=$(date +%s)
timeout 300 python -m searchrl.evaluate checkpoint=runs/reference/term/b/model.zip device=cuda threads=16 \
    progress_bar=false bound_cache=runs/device_bounds out_dir=runs/eval/gpu/term_b >>"$LOG" 2>&1
say "full-grid evaluation: rc $? after $(( $(date +%s) - start )) s, $(ls runs/eval/gpu/term_b/cells 2>/dev/null \
    | wc -l) cell files"
tar czf "$OUT/gpu_term_b_eval.tgz" -C runs/eval/gpu term_b 2>/dev/null

say "bench world: 1 and 16 threads"
timeout 60 python -m searchrl.bench world --threads 1,16 --seconds 2 --json 2>>"$LOG" | tee -a "$JSON"

say "profile: one n = 160 cell (N = 8) of term/b on cuda, its bounds included (cProfile, cumulative)"
P="grid.world_sizes=[160] grid.n_targets=[32] grid.n_distributions=[64] grid.max_agents=[256] grid.agents=[8]"
timeout 120 python -m cProfile -o "$OUT/eval_n160_N8.prof" -m searchrl.evaluate \
    checkpoint=runs/reference/term/b/model.zip device=cuda threads=16 $P progress_bar=false \
    bound_cache=null out_dir=runs/eval/gpu/profile >>"$LOG" 2>&1
python -c "import pstats, sys; pstats.Stats(sys.argv[1]).sort_stats('cumulative').print_stats(45)" \
    "$OUT/eval_n160_N8.prof" > "$OUT/eval_n160_N8_profile.txt" 2>&1

left=$(( BUDGET - ($(date +%s) - T0) ))
say "train: +model=c machine=gpu for the ${left} s left"
start=$(date +%s)
timeout "$left" python -m searchrl.train +model=c machine=gpu progress_bar=false hydra.run.dir=runs/train/gpu/c \
    >>"$LOG" 2>&1
say "+model=c: rc $? after $(( $(date +%s) - start )) s"
for f in progress.csv config.yaml; do cp runs/train/gpu/c/$f "$OUT/gpu_c_$f" 2>/dev/null; done
say "done"
