#!/usr/bin/env bash
# The figures of docs/performance.md#machines that need a GPU machine, measured in one run (under 10 minutes on one
# H100/H200 with 16 cores), most needed first: training throughput and the shares of its wall time on the GPU, B's
# recipe trained whole with machine=gpu (its model comes back for the paired check on two cores), 90 s of the
# paper's recipe in model C's world (its rate), evaluation of term/b, the world at 1 and 16 threads.
#   bash analysis/device_check.sh            # results under $OUT (the device tool's folder) or runs/device/
set -uo pipefail
OUT=${OUT:-runs/device}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
LOG="$OUT/log.txt"
JSON="$OUT/bench.jsonl"
say() { echo "== $(date +%T) $*" | tee -a "$LOG"; }
B="timeout 150 python -m searchrl.bench"   # each step bounded: one stuck step leaves the rest their time

say "machine"
{ nvidia-smi --query-gpu=name,memory.total --format=csv,noheader; nproc
  python -c "import torch, numba, numpy; print('torch', torch.__version__, 'numba', numba.__version__, \
'numpy', numpy.__version__, 'cuda', torch.cuda.is_available())"; } 2>&1 | tee -a "$LOG"

say "bench train: B's recipe, machine=gpu"
$B train --experiment rl_term_b --machine gpu --updates 3 --json 2>>"$LOG" | tee -a "$JSON"

say "train: B's recipe whole, machine=gpu"
start=$(date +%s)
timeout 240 python -m searchrl.train +experiment=rl_term_b machine=gpu progress_bar=false \
    hydra.run.dir=runs/train/gpu/b >>"$LOG" 2>&1
say "B's recipe: rc $? after $(( $(date +%s) - start )) s"
for f in model.zip progress.csv config.yaml; do cp runs/train/gpu/b/$f "$OUT/gpu_b_$f" 2>/dev/null; done

say "train: +model=c machine=gpu, 90 s of it"
timeout 90 python -m searchrl.train +model=c machine=gpu progress_bar=false hydra.run.dir=runs/train/gpu/c \
    >>"$LOG" 2>&1
cp runs/train/gpu/c/progress.csv "$OUT/gpu_c_progress.csv" 2>/dev/null

say "bench eval: term/b on the GPU and on 16 CPU threads"
for d in cuda cpu; do
  $B eval --checkpoint runs/reference/term/b/model.zip --device $d --threads 16 --maps 2 --json 2>>"$LOG" \
    | tee -a "$JSON"
done
say "bench world: 1 and 16 threads"
$B world --threads 1,16 --seconds 2 --json 2>>"$LOG" | tee -a "$JSON"
say "bench train: B's recipe on the GPU at its own 384 slots and minibatch"
$B train --experiment rl_term_b --device cuda --threads 16 --updates 4 --json 2>>"$LOG" | tee -a "$JSON"
say "done"
