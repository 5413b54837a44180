#!/usr/bin/env bash
# Branches of the finished pbt-ld2 s = 1/4 run (200 rev, explicit), continued from its last
# checkpoint to REVS revolutions: lim2 (lubrication limiter, 2 contact sub-steps) and ctl
# (explicit, 8 sub-steps: the paired control). Each resumes from its own directory (a copy of the
# 200-revolution run at first). The campaign is paused meanwhile.
# Run as `branches-ld2.sh 235`, then `branches-ld2.sh 270` (2026-11-25/26). The second call ran
# lim2 without --switch-contacts (its checkpoint already had the limiter's scheme); the flag only
# relaxes the checkpoint's fingerprint check, so the numbers are the same either way.
REVS=${1:?usage: branches-ld2.sh REVOLUTIONS}
cd ~/slurry-runs
BIN=./bin/slurry-0f8501a; REV=0f8501a
CAMP=$(pgrep -f 'bin/slurry-a94570f reproduce')
[ -n "$CAMP" ] && kill -STOP $CAMP
run() { out=~/slurry-runs/pbt-ld2-s0.25-$1; shift
  echo "== $out $(date -u +%FT%TZ) $*"
  SLURRY_GIT_REVISION=$REV $BIN reproduce pbt-ld2 --scale 0.25 --revolutions $REVS --mach-limit 0.35 \
    --out $out --cache ~/slurry-runs/cache --resume "$@"; echo "rc $?"; }
run lim2 --switch-contacts --contact-substeps 2 --lubrication-limiter
run ctl
[ -n "$CAMP" ] && kill -CONT $CAMP
echo "== done $(date -u +%FT%TZ)"
