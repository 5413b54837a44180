#!/usr/bin/env bash
# campaign.sh RUNS SCALE CASE... [-- SLURRY-OPTION...] : reproduce the given cases at scale SCALE
# to steady state, one after the other, in RUNS/CASE-sSCALE/ (a directory outside the checkout, so that a fresh clone
# or `cargo clean` never deletes hours of stepping).
#
# - Each case runs `slurry reproduce CASE --scale SCALE --revolutions 100 --until-steady 200`
#   (pbt-ld1: 200 and 300, the paper's "more than 200 revolutions"), beds cached in RUNS/cache.
#   REVOLUTIONS and CAP (environment) replace these numbers for every case; options after `--`
#   are passed to each `slurry reproduce` (e.g. `-- --contact-substeps 4 --mach-limit 0.4`).
# - Started again, it resumes a case that has a checkpoint (`--resume`) and skips one that has
#   finished (RUNS/CASE-sSCALE/DONE); it never starts a case afresh over an earlier run (slurry
#   refuses that itself unless --overwrite).
# - A lane stops at its first failure (a Mach-limit stop, a full disk), leaving the checkpoint
#   for a resume, while the other lanes go on; the exit status is 1 if any lane failed. The log
#   is RUNS/CASE-sSCALE/log.txt, the campaign's own lines go to stdout. Stopping the campaign
#   (SIGINT or SIGTERM to this script) stops its runs at a checkpoint of the step each has
#   reached (slurry's own answer to SIGTERM), so that a session's end loses no stepping.
# - BIN (default: target/release/slurry of this checkout, built if missing) is the binary; give
#   a copy outside the checkout for a campaign that spans sessions, so that the stepping bits
#   cannot change under it.
#
# - LANES (default 1): run the cases in this many concurrent lanes (cases dealt round-robin,
#   each lane one case after another), each with cores/LANES threads (at least 1; with
#   LANES = 1 slurry's default, all cores or RAYON_NUM_THREADS). A case named twice runs once. The results do not
#   change (the stepping is bitwise the same for any thread count); only the throughput does.
#   Measured 2026-11-27 on the 2-core VM (campaign paused): two 1-thread runs side by side took
#   212.8 and 213.5 ms per step for pbt-ld2 at s = 1/2 from its bed, against 121.4 ms for one
#   2-thread run (1.14 times the steps per second in all); disk-ld1 at s = 1/4 from its steady
#   checkpoint 57.6 and 63.7 against 35.3 ms (1.16 times). Each case takes about 1.75 times
#   longer, so lanes pay only when there are at least as many cases as lanes. On the Intel Xeon
#   VM of 2026-11-30 they do not pay: pbt-ld2 at s = 1/2 took 177 ms per step on 1 thread and
#   92 ms on 2 (1.93 times), so a second lane could add at most 4 %. THREADS
#   (environment) sets the threads per lane instead (e.g. THREADS=2 for one case on 2 cores).
#
# - FROM (environment, a scale below SCALE, e.g. FROM=0.25): each case first runs at scale FROM to
#   steady state (in RUNS/CASE-sFROM/, as above, skipped when done), then at SCALE **from that
#   run's state at its end** (`--start-from RUNS/CASE-sFROM/run`; steady, or at the cap of
#   200 revolutions where the test never passed, as disk-ld1 at s = 1/4 would), in far fewer revolutions than
#   from the bed (pbt-ld2 at s = 1/2: steady after 100 revolutions from the s = 1/4 state,
#   against an estimated 200 or more from the bed, which rises about half as fast as at
#   s = 1/4). Where the finer level is lower, as for pbt-ld2 (0.322 → 0.281), it is approached
#   from above; the coarse verdict itself can come on a slow rise (disk-ld4 at s = 1/4: 0.327 at
#   100 revolutions, 0.337 later), so the direction is not guaranteed. Archive the coarse run too
#   (archive.sh writes its start pack), so that the start survives the runs directory.
#
# - Each leg's end (a case finished, or stopped by a signal or an error at a checkpoint) writes
#   the case's state pack, RUNS/CASE-sSCALE/state.h5 (`slurry state-pack`: the flow, every body
#   and the run's history, its time series and legs; 5-6 MB at s = 1/4, under 40 MB at s = 1/2).
#   Started again where the case has no checkpoint but that pack, it continues from the pack
#   (`--start-from`), as one run: the time series goes on, the legs are counted in its
#   manifest. Commit the pack (reproduce/tools/save-leg.sh) to continue on another machine:
#   copy it back to RUNS/CASE-sSCALE/state.h5 there and run the same command.
#
# After a machine loss with no pack: the same command starts each case again from its dry bed;
# the stepping is deterministic, so the runs repeat their lost predecessors bitwise.
#
# Example: nohup reproduce/tools/campaign.sh ~/slurry-runs 0.5 pbt-ld2 pbt-ld4 >> ~/slurry-runs/campaign.log 2>&1 &
#          LANES=2 nohup reproduce/tools/campaign.sh ~/slurry-runs 0.5 disk-ld1 disk-ld2 disk-ld4 pbt-ld4 >> ... &
set -u
if [ $# -lt 3 ]; then sed -n '2,/^set -u/p' "$0" | sed '$d'; exit 2; fi
runs=$1 scale=$2; shift 2
# The cases, then the options for slurry after `--`.
names=() extra=()
while [ $# -gt 0 ]; do
  if [ "$1" = -- ]; then shift; extra=("$@"); break; fi
  names+=("$1"); shift
done
if [ ${#names[@]} -eq 0 ]; then echo "campaign.sh: no case given" >&2; exit 2; fi
for v in REVOLUTIONS CAP THREADS; do
  if [ -n "${!v:-}" ] && ! [[ ${!v} =~ ^[1-9][0-9]*$ ]]; then echo "campaign.sh: $v=${!v}: a positive integer" >&2; exit 2; fi
done
FROM=${FROM:-}
if [ -n "$FROM" ] && ! awk -v f="$FROM" -v s="$scale" 'BEGIN { exit !(f + 0 > 0 && f + 0 < s + 0) }'; then
  echo "campaign.sh: FROM=$FROM: a scale above 0 and below SCALE = $scale" >&2; exit 2
fi
root=$(cd "$(dirname "$0")/../.." && pwd)
BIN=${BIN:-$root/target/release/slurry}
if [ ! -x "$BIN" ]; then (cd "$root" && cargo build --release --bin slurry) || exit 1; fi
mkdir -p "$runs/cache"
LANES=${LANES:-1}
if ! [[ $LANES =~ ^[1-9][0-9]*$ ]]; then echo "campaign.sh: LANES=$LANES: a positive integer" >&2; exit 2; fi
threads=()
if [ "$LANES" -gt 1 ]; then
  cores=$(getconf _NPROCESSORS_ONLN)
  t=$(( cores / LANES )); [ "$t" -ge 1 ] || t=1
  threads=(--threads "$t")
fi
if [ -n "${THREADS:-}" ]; then threads=(--threads "$THREADS"); fi
# One case: skipped if done, resumed if it has a checkpoint; non-zero on failure.
# With FROM, the case at scale FROM first, then at SCALE from its state.
run_case() {
  if [ -n "$FROM" ]; then
    run_at "$1" "$FROM" || return 1
    run_at "$1" "$scale" --start-from "$runs/$1-s$FROM/run"
  else
    run_at "$1" "$scale"
  fi
}
# One case at one scale (then extra options for slurry).
run_at() {
  local c=$1 s=$2 revs=100 cap=200; shift 2
  local d=$runs/$c-s$s
  if [ -f "$d/DONE" ]; then echo "$(date -u +%FT%TZ) $c s$s: done, skipped"; return 0; fi
  mkdir -p "$d"
  if [ "$c" = pbt-ld1 ]; then revs=200 cap=300; fi
  revs=${REVOLUTIONS:-$revs} cap=${CAP:-$cap}
  if [ "$cap" -lt "$revs" ]; then echo "$(date -u +%FT%TZ) $c s$s: CAP=$cap is below the $revs revolutions asked for" >&2; return 1; fi
  local args=(reproduce "$c" --scale "$s" --revolutions $revs --until-steady $cap --out "$d/run" --cache "$runs/cache" "${threads[@]}" --quiet "$@" "${extra[@]}")
  if [ -f "$d/run/run/checkpoint.h5" ]; then
    args+=(--resume)
  elif [ -f "$d/state.h5" ]; then
    # The run directory is gone but a leg's pack is there (kept, or copied back from the
    # checkout's archive): the run goes on from it, as one run.
    args=(reproduce "$c" --scale "$s" --revolutions $revs --until-steady $cap --out "$d/run" --cache "$runs/cache" "${threads[@]}" --quiet --overwrite --start-from "$d/state.h5" "${extra[@]}")
  fi
  echo "$(date -u +%FT%TZ) $c s$s: $BIN ${args[*]}"
  # In the background, so that the SIGTERM that stop() sends this lane reaches its trap at once
  # and is passed on: slurry then stops at a checkpoint of the step it has reached. (A lane,
  # itself started in the background, ignores SIGINT; stop() answers that one.)
  "$BIN" "${args[@]}" >> "$d/log.txt" 2>&1 &
  local child=$! rc
  trap 'kill -TERM $child 2>/dev/null' TERM
  while true; do
    wait $child; rc=$?
    kill -0 $child 2>/dev/null || break
  done
  trap - TERM
  # The leg's end, finished or stopped at a checkpoint: its state pack, the run's whole state
  # and history in a few megabytes (commit it to continue on another machine).
  if [ -f "$d/run/run/checkpoint.h5" ]; then
    "$BIN" state-pack "$d/run/run" "$d/state.h5.new" --label "$c at s = $s" >> "$d/log.txt" 2>&1 \
      && mv "$d/state.h5.new" "$d/state.h5" && echo "$(date -u +%FT%TZ) $c s$s: state pack $d/state.h5"
  fi
  if [ $rc -eq 0 ]; then
    touch "$d/DONE"; echo "$(date -u +%FT%TZ) $c s$s: finished"
  else
    echo "$(date -u +%FT%TZ) $c s$s: stopped (exit status $rc), see $d/log.txt"; return 1
  fi
}
# One lane: its cases one after another, stopping at the first failure.
lane() { for c in "$@"; do run_case "$c" || return 1; done; }
# Each case once, in the order given.
cases=() pids=()
for c in "${names[@]}"; do
  dup=0; for k in "${cases[@]}"; do [ "$k" = "$c" ] && dup=1; done
  [ $dup -eq 1 ] || cases+=("$c")
done
# Stopping the campaign (SIGINT or SIGTERM) sends one SIGTERM to each lane, which passes it on
# to its slurry (a second signal would end slurry at once, without its checkpoint), and waits
# for the runs to stop at their checkpoints.
stop() {
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null; done
  wait
  exit 143
}
trap stop INT TERM
for ((l = 0; l < LANES; l++)); do
  mine=()
  for ((i = l; i < ${#cases[@]}; i += LANES)); do mine+=("${cases[i]}"); done
  [ ${#mine[@]} -gt 0 ] || continue
  lane "${mine[@]}" & pids+=($!)
done
status=0
for p in "${pids[@]}"; do wait "$p" || status=1; done
exit $status
