#!/usr/bin/env bash
# The guided policy of research/guided_b_plan (analysis/guided_b.py, GUIDED_PLAN=1) on both frozen suites, beside the
# rules that lead them (path_greedy among walls, B's teacher on the open grid and with the prior right, coverage and
# the evidence switch where the prior misleads) and the shipped policies, then the suites' tables and paired
# comparisons. One core; hours. Every evaluation resumes where it stopped: run it again after an interruption.
#   bash analysis/guided_suites.sh [obstacles|prior_error]...     # both suites by default, obstacles first
set -euo pipefail
GUIDED=${GUIDED:-runs/train/guided/b_plan/model.zip}
T="threads=1 progress_bar=false"
guided() { GUIDED_PLAN=1 python analysis/guided_b.py evaluate suite=$1 checkpoint="$GUIDED" $T \
    out_dir=runs/suite/$1/policy/guided/b_plan; }
rule() { local s=$1; shift; python -m searchrl.evaluate suite=$s +model=b $T "$@"; }
policy() { python -m searchrl.evaluate suite=$1 checkpoint=runs/reference/$2/model.zip $T; }
SUITES=${*:-obstacles prior_error}
for s in $SUITES; do  # every name checked before any evaluation starts
  case $s in obstacles|prior_error) ;; *) echo "error: suite $s is not allowed: obstacles or prior_error" >&2; exit 2;; esac
done
for s in $SUITES; do
  guided $s
  case $s in
    obstacles)
      rule $s controller=path_greedy
      rule $s controller=greedy_target controller.reach=2
      policy $s walls/b;;
    prior_error)
      rule $s controller=greedy_target controller.reach=2
      rule $s controller=coverage
      rule $s controller=switch controller.threshold=0.25
      policy $s robust/b;;
  esac
  python analysis/suite.py runs/suite/$s --focus policy:train/guided/b_plan --out analysis/out/suite_$s/guided_b_plan
done
