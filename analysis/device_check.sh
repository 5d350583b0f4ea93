#!/usr/bin/env bash
# The figures of docs/performance.md#machines that need a GPU machine, measured in one run (under ten minutes on one
# H100/H200 with 16 cores), most needed first: numba's compile on the fresh machine (a one-cell evaluation of term/b
# on the GPU, timed apart: every later command loads the cache it leaves); a whole full-grid evaluation of term/b on
# the GPU from a new bound cache, which starts from the shipped bounds (runs/reference/bounds: no bound of the
# grid's maps is computed; timed end to end, at most 300 s, each cell's time from its file's); the world at 1 and 16
# threads (and one crowded world's step, analysis/one_world.py); B's recipe's throughput and the shares of its wall
# time at machine=gpu; where the time of one n = 160 cell goes (cProfile), only when the full grid did not finish;
# then the paper's `+model=c` at machine=gpu for the time left.
#
# `+model=c` (18.4M agent-steps) takes longer than one call on a lent machine, so it runs in segments: its run
# folder comes back under $OUT/gpu_c/ (config, progress.csv, the newest checkpoint, and model.zip at the end), and a
# later call that carries it back to runs/train/gpu/c resumes it there; the segments' times add up to the run's.
#   bash analysis/device_check.sh [seconds]  # the whole script's time (560 by default; +model=c gets the rest);
#                                            # results under $OUT (the folder the device tool gives) or runs/device/
set -uo pipefail
OUT=${OUT:-runs/device}
BUDGET=${1:-560}
RUN=runs/train/gpu/c
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
LOG="$OUT/log.txt"
JSON="$OUT/bench.jsonl"
T0=$(date +%s)
say() { echo "== $(date +%T) +$(( $(date +%s) - T0 ))s $*" | tee -a "$LOG"; }
newest() { ls "$RUN"/checkpoints 2>/dev/null | sort -t_ -k2 -n | tail -1; }  # step_<agent-steps>.zip

say "machine"
{ nvidia-smi --query-gpu=name,memory.total --format=csv,noheader; nproc; git rev-parse --short HEAD 2>/dev/null
  python -c "import torch, numba, numpy; print('torch', torch.__version__, 'numba', numba.__version__, \
'numpy', numpy.__version__, 'cuda', torch.cuda.is_available())"; } 2>&1 | tee -a "$LOG"

say "compile: term/b on one small cell, device=cuda threads=16, an empty numba cache"
start=$(date +%s)
timeout 240 python -m searchrl.evaluate checkpoint=runs/reference/term/b/model.zip device=cuda threads=16 \
    grid.world_sizes=[20] grid.n_targets=[4] grid.n_distributions=[8] grid.max_agents=[2] grid.maps_per_cell=1 \
    grid.repeats=1 progress_bar=false out_dir=runs/eval/gpu/compile >>"$LOG" 2>&1
say "compile: rc $? after $(( $(date +%s) - start )) s"

say "evaluate: term/b on the full grid, device=cuda threads=16, a new bound cache (the shipped bounds)"
start=$(date +%s)
timeout 300 python -m searchrl.evaluate checkpoint=runs/reference/term/b/model.zip device=cuda threads=16 \
    progress_bar=false bound_cache=runs/device_bounds out_dir=runs/eval/gpu/term_b >>"$LOG" 2>&1
rc=$?
cells=$(ls runs/eval/gpu/term_b/cells 2>/dev/null | wc -l)
say "full-grid evaluation: rc $rc after $(( $(date +%s) - start )) s, $cells cell files"
ls -l --time-style=+%T runs/eval/gpu/term_b/cells 2>/dev/null | awk 'NF > 6 {print $6, $7}' | tee -a "$LOG"
tar czf "$OUT/gpu_term_b_eval.tgz" -C runs/eval/gpu term_b 2>/dev/null

say "bench world: 1 and 16 threads"
timeout 60 python -m searchrl.bench world --threads 1,16 --seconds 4 --json 2>>"$LOG" | tee -a "$JSON"

say "one crowded world: target-greedy's moves replayed at 1 and 16 threads (its merge shared among them)"
timeout 60 python analysis/one_world.py 2>&1 | tee -a "$LOG"

say "bench train: B's recipe, machine=gpu"
timeout 150 python -m searchrl.bench train --experiment term/b --machine gpu --updates 3 --json 2>>"$LOG" \
    | tee -a "$JSON"

if [ "$cells" -lt 30 ]; then
    say "profile: one n = 160 cell (N = 128) of term/b on cuda from the shipped bounds (cProfile, cumulative)"
    P="grid.world_sizes=[160] grid.n_targets=[32] grid.n_distributions=[64] grid.max_agents=[256] grid.agents=[128]"
    timeout 100 python -m cProfile -o "$OUT/eval_n160_N128.prof" -m searchrl.evaluate \
        checkpoint=runs/reference/term/b/model.zip device=cuda threads=16 $P grid.maps_per_cell=20 \
        progress_bar=false bound_cache=runs/device_bounds out_dir=runs/eval/gpu/profile >>"$LOG" 2>&1
    python -c "import pstats, sys; pstats.Stats(sys.argv[1]).sort_stats('tottime').print_stats(40)" \
        "$OUT/eval_n160_N128.prof" > "$OUT/eval_n160_N128_profile.txt" 2>&1
fi

left=$(( BUDGET - ($(date +%s) - T0) ))
start=$(date +%s)
if [ -n "$(newest)" ]; then
    say "train: +model=c machine=gpu, resumed from $(newest), for the ${left} s left"
    timeout "$left" python -m searchrl.train resume="$RUN" device=cuda progress_bar=false >>"$LOG" 2>&1
else
    say "train: +model=c machine=gpu for the ${left} s left"
    timeout "$left" python -m searchrl.train +model=c machine=gpu progress_bar=false hydra.run.dir="$RUN" \
        >>"$LOG" 2>&1
fi
say "+model=c: rc $? after $(( $(date +%s) - start )) s"
mkdir -p "$OUT/gpu_c/checkpoints"
for f in config.yaml progress.csv score.json model.zip; do cp "$RUN/$f" "$OUT/gpu_c/" 2>/dev/null; done
[ -n "$(newest)" ] && cp "$RUN/checkpoints/$(newest)" "$OUT/gpu_c/checkpoints/"
say "done"
