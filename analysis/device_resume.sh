#!/usr/bin/env bash
# Long trainings resumed side by side on a lent GPU machine, each on its share of the cores, for a fixed time; each
# comes back as one archive to continue anywhere. Prepare the runs here (the newest checkpoint of each, without its
# optimiser's moments, so that four fit the device tool's 64 MiB beside the repository), carry `.gpu` and the wheels:
#   python analysis/carry_runs.py --to .gpu --without-moments runs/train/research/critic_b ...   # here
#   bash analysis/device_resume.sh SECONDS THREADS [--device cpu] [--reserve S] [--no-bench] NAME[=TOTAL] ...  # there
# The wheels (.whl) are the pure-Python packages the machine's image lacks (pip download --no-deps stable-baselines3
# sb3-contrib gymnasium farama-notifications hydra-core omegaconf pettingzoo, pip wheel antlr4-python3-runtime), put
# first on the path there: `export PATH=/opt/torch/.venv/bin:$PATH; python -m pip install -q --no-index --no-deps
# --target /tmp/site .whl/*.whl && export PYTHONPATH=/tmp/site`.
# Each NAME is a run folder under .gpu/; TOTAL its new total of agent-steps (default: its own). The runs are stopped
# with SIGTERM (each writes a checkpoint at the end of its rollout) so that the whole script ends within SECONDS.
# Under $OUT (runs/device by default): NAME.tgz (the run folder less TensorBoard's log, its newest checkpoint whole
# and the first one past each of 3M, 10M and 30M agent-steps without moments), log.txt, and the world's speed at 1
# and 16 threads measured on the idle machine at the end (bench.jsonl). Unpack with `tar xzf NAME.tgz -C
# runs/train/research` and resume there.
set -uo pipefail
OUT=${OUT:-runs/device}
USAGE="usage: bash analysis/device_resume.sh SECONDS THREADS [--device D] [--reserve S] [--no-bench] NAME[=TOTAL] ..."
if [ $# -lt 3 ] || ! [[ $1 =~ ^[0-9]+$ && $2 =~ ^[0-9]+$ ]]; then echo "$USAGE" >&2; exit 2; fi
SECONDS_TOTAL=$1; THREADS=$2; shift 2
DEVICE=cuda; RESERVE=120; BENCH=1  # RESERVE: for the last rollouts' checkpoints (at most 45 s), the bench, the packing
while [[ ${1:-} == --* ]]; do
    case $1 in
        --device) DEVICE=$2; shift 2 ;;
        --reserve) RESERVE=$2; shift 2 ;;
        --no-bench) BENCH=0; shift ;;
        *) echo "device_resume: unknown option $1 ($USAGE)" >&2; exit 2 ;;
    esac
done
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
LOG="$OUT/log.txt"
T0=$(date +%s)
say() { echo "== $(date +%T) +$(( $(date +%s) - T0 ))s $*" | tee -a "$LOG"; }

say "machine"
{ nvidia-smi --query-gpu=name,memory.total --format=csv,noheader; nproc; git rev-parse --short HEAD 2>/dev/null
  python -c "import torch, numba, numpy; print('torch', torch.__version__, 'numba', numba.__version__, \
'numpy', numpy.__version__, 'cuda', torch.cuda.is_available())"; } 2>&1 | tee -a "$LOG"

train_for=$(( SECONDS_TOTAL - RESERVE - ($(date +%s) - T0) ))
say "resume ${*} for ${train_for} s at threads=${THREADS} device=${DEVICE}"
steps_of() { ls "$1/checkpoints" | sed 's/step_\([0-9]*\).zip/\1/' | sort -n; }
declare -A carried  # each run's step on arrival: a checkpoint packed for a mark is one trained here
for spec in "$@"; do carried[${spec%%=*}]=$(steps_of ".gpu/${spec%%=*}" | tail -1); done
pids=()
for spec in "$@"; do
    name=${spec%%=*}
    total=()
    [[ $spec == *=* ]] && total=("total_timesteps=${spec#*=}")
    timeout -k 45 -s TERM "$train_for" python -m searchrl.train resume=".gpu/$name" device="$DEVICE" \
        threads="$THREADS" progress_bar=false "${total[@]}" > "$OUT/$name.out" 2>&1 &
    pids+=($!)
done
for i in "${!pids[@]}"; do wait "${pids[$i]}"; say "${*:$((i + 1)):1}: rc $?"; done

if [ "$BENCH" = 1 ]; then
    say "bench world: 1 and 16 threads, the machine idle"
    timeout 40 python -m searchrl.bench world --threads 1,16 --seconds 4 --json 2>>"$LOG" | tee -a "$OUT/bench.jsonl"
fi

for spec in "$@"; do
    run=.gpu/${spec%%=*}
    tail -20 "$OUT/${spec%%=*}.out" >> "$LOG"
    steps=$(steps_of "$run" | awk -v c="${carried[${spec%%=*}]}" '$1 > c')
    last=$(steps_of "$run" | tail -1)
    keep=("checkpoints/step_$last.zip")
    for mark in 3000000 10000000 30000000; do
        past=$(echo "$steps" | awk -v m="$mark" '$1 >= m' | head -1)
        if [ -n "$past" ] && [ "$past" != "$last" ]; then
            python -m searchrl.policies.slim "$run/checkpoints/step_$past.zip" >> "$LOG" 2>&1
            keep+=("checkpoints/step_$past.zip")
        fi
    done
    files=$(cd "$run" && ls -A | grep -v -x -e checkpoints -e tensorboard -e .lock)
    tar czf "$OUT/${spec%%=*}.tgz" -C .gpu $(for f in $files "${keep[@]}"; do echo "${spec%%=*}/$f"; done)
    rm -f "$OUT/${spec%%=*}.out"
    say "${spec%%=*}: packed at step $last with ${keep[*]}"
done
say "done"
