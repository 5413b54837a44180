#!/usr/bin/env bash
# Branches of the finished pbt-ld2 s = 1/4 run (200 rev, explicit) continued to 235 rev, then (this script) to 270 from its
# last checkpoint: lim2 (lubrication limiter, 2 contact sub-steps, --switch-contacts) and ctl
# (explicit, 8 sub-steps: the paired control). The campaign is paused meanwhile.
cd ~/slurry-runs
BIN=./bin/slurry-0f8501a; REV=0f8501a
CAMP=$(pgrep -f 'bin/slurry-a94570f reproduce')
[ -n "$CAMP" ] && kill -STOP $CAMP
run() { out=~/slurry-runs/pbt-ld2-s0.25-$1; shift
  echo "== $out $(date -u +%FT%TZ) $*"
  SLURRY_GIT_REVISION=$REV $BIN reproduce pbt-ld2 --scale 0.25 --revolutions 270 --mach-limit 0.35 \
    --out $out --cache ~/slurry-runs/cache --resume "$@"; echo "rc $?"; }
run lim2 --contact-substeps 2 --lubrication-limiter
run ctl
[ -n "$CAMP" ] && kill -CONT $CAMP
echo "== done $(date -u +%FT%TZ)"
