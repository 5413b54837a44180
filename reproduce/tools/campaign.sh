#!/usr/bin/env bash
# campaign.sh RUNS SCALE CASE... : reproduce the given cases at scale SCALE to steady state, one
# after the other, in RUNS/CASE-sSCALE/ (a directory outside the checkout, so that a fresh clone
# or `cargo clean` never deletes hours of stepping).
#
# - Each case runs `slurry reproduce CASE --scale SCALE --revolutions 100 --until-steady 200`
#   (pbt-ld1: 200 and 300, the paper's "more than 200 revolutions"), beds cached in RUNS/cache.
# - Started again, it resumes a case that has a checkpoint (`--resume`) and skips one that has
#   finished (RUNS/CASE-sSCALE/DONE); it never starts a case afresh over an earlier run (slurry
#   refuses that itself unless --overwrite).
# - It stops at the first failure (a Mach-limit stop, a full disk), leaving the checkpoint for a
#   resume; the log is RUNS/CASE-sSCALE/log.txt, the campaign's own lines go to stdout.
# - BIN (default: target/release/slurry of this checkout, built if missing) is the binary; give
#   a copy outside the checkout for a campaign that spans sessions, so that the stepping bits
#   cannot change under it.
#
# Example: nohup reproduce/tools/campaign.sh ~/slurry-runs 0.5 pbt-ld2 pbt-ld4 >> ~/slurry-runs/campaign.log 2>&1 &
set -u
if [ $# -lt 3 ]; then sed -n '2,20p' "$0"; exit 2; fi
runs=$1 scale=$2; shift 2
root=$(cd "$(dirname "$0")/../.." && pwd)
BIN=${BIN:-$root/target/release/slurry}
if [ ! -x "$BIN" ]; then (cd "$root" && cargo build --release --bin slurry) || exit 1; fi
mkdir -p "$runs/cache"
for c in "$@"; do
  d=$runs/$c-s$scale
  if [ -f "$d/DONE" ]; then echo "$(date -u +%FT%TZ) $c s$scale: done, skipped"; continue; fi
  mkdir -p "$d"
  revs=100 cap=200
  if [ "$c" = pbt-ld1 ]; then revs=200 cap=300; fi
  args=(reproduce "$c" --scale "$scale" --revolutions $revs --until-steady $cap --out "$d/run" --cache "$runs/cache" --quiet)
  if [ -f "$d/run/run/checkpoint.h5" ]; then args+=(--resume); fi
  echo "$(date -u +%FT%TZ) $c s$scale: $BIN ${args[*]}"
  if "$BIN" "${args[@]}" >> "$d/log.txt" 2>&1; then
    touch "$d/DONE"; echo "$(date -u +%FT%TZ) $c s$scale: finished"
  else
    rc=$?; echo "$(date -u +%FT%TZ) $c s$scale: failed (exit status $rc), see $d/log.txt"; exit 1
  fi
done
