#!/usr/bin/env bash
# The figures of docs/performance.md#machines that need a GPU machine, measured in one run (under 10 minutes on one
# H100/H200 with 16 cores), most needed first: B's recipe's throughput and the shares of its wall time at
# machine=gpu, 60 s of the paper's recipe in model C's world (its rate), a whole full-grid evaluation of term/b on
# the GPU (timed end to end), the world at 1 and 16 threads, the 16-core CPU machine, then B's recipe trained with
# machine=gpu for what time is left (its progress.csv and, if it finishes, its model come back).
#   bash analysis/device_check.sh            # results under $OUT (the device tool's folder) or runs/device/
set -uo pipefail
OUT=${OUT:-runs/device}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
LOG="$OUT/log.txt"
JSON="$OUT/bench.jsonl"
say() { echo "== $(date +%T) $*" | tee -a "$LOG"; }
B="timeout 100 python -m searchrl.bench"   # each step bounded: one stuck step leaves the rest their time

say "machine"
{ nvidia-smi --query-gpu=name,memory.total --format=csv,noheader; nproc
  python -c "import torch, numba, numpy; print('torch', torch.__version__, 'numba', numba.__version__, \
'numpy', numpy.__version__, 'cuda', torch.cuda.is_available())"; } 2>&1 | tee -a "$LOG"

say "bench train: B's recipe, machine=gpu"
$B train --experiment term/b --machine gpu --updates 3 --json 2>>"$LOG" | tee -a "$JSON"

say "train: +model=c machine=gpu, 60 s of it"
timeout 60 python -m searchrl.train +model=c machine=gpu progress_bar=false hydra.run.dir=runs/train/gpu/c \
    >>"$LOG" 2>&1
cp runs/train/gpu/c/progress.csv "$OUT/gpu_c_progress.csv" 2>/dev/null

say "evaluate: term/b on the full grid, device=cuda threads=16"
start=$(date +%s)
timeout 280 python -m searchrl.evaluate checkpoint=runs/reference/term/b/model.zip device=cuda threads=16 \
    out_dir=runs/eval/gpu/term_b >>"$LOG" 2>&1
say "full-grid evaluation: rc $? after $(( $(date +%s) - start )) s, $(ls runs/eval/gpu/term_b/cells 2>/dev/null | wc -l) cell files"
tar czf "$OUT/gpu_term_b_eval.tgz" -C runs/eval/gpu term_b 2>/dev/null

say "bench world: 1 and 16 threads"
$B world --threads 1,16 --seconds 2 --json 2>>"$LOG" | tee -a "$JSON"
say "bench train: B's recipe, machine=cpu16"
timeout 60 python -m searchrl.bench train --experiment term/b --machine cpu16 --updates 1 --json 2>>"$LOG" \
    | tee -a "$JSON"

say "train: B's recipe, machine=gpu, for the time left"
start=$(date +%s)
timeout 80 python -m searchrl.train +experiment=term/b machine=gpu progress_bar=false \
    hydra.run.dir=runs/train/gpu/b >>"$LOG" 2>&1
say "B's recipe: rc $? after $(( $(date +%s) - start )) s"
for f in model.zip progress.csv; do cp runs/train/gpu/b/$f "$OUT/gpu_b_$f" 2>/dev/null; done
say "done"
