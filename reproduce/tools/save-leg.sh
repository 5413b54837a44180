#!/usr/bin/env bash
# save-leg.sh RUN_OUT DEST : keep a reproduction that has not finished (the --out directory of
# `slurry reproduce`, running or stopped at a checkpoint) as one **leg** of a campaign, in the
# checkout's archive, e.g. reproduce/CASE/runs/DATE-sSCALE-below-leg1/: manifest.json,
# start.json (a run started with --start-from), the leg's own rows of run/timeseries.csv as
# DEST/timeseries.csv, and a start pack of its
# last frames in DEST/start/ (`slurry start-pack`, under 1 MB), so that the next leg can
# `--start-from DEST/start` once RUN_OUT is gone with the machine; and a state pack of its
# checkpoint, DEST/state.h5 (`slurry state-pack`: the whole state and the run's history, 5-6 MB
# at s = 1/4, at most 40 MB at s = 1/2), so that the next leg continues the run itself:
# `slurry reproduce CASE --scale S --start-from DEST/state.h5 --revolutions R` (R past the pack).
#
# Why: the campaign's runs directory was lost with the machine at six session ends
# (reproduce/JOURNAL.md, "The campaign's history"); a run at s = 1/2 needs 10-14 h of stepping,
# several sessions. A leg continued from the state pack goes on from where the last one
# stopped, as the same run (flow rebuilt from density and velocity, particles exact: no
# transient; the pack carries the run's time series and legs, so the series goes on as one,
# the steady test reads it across legs, and manifest.json counts the legs). A pack written
# before packs carried the history (layout version 1) starts a series of its own. A leg
# started from the start pack is a new run (particles at rest, the fluid at rest and the
# impeller's ramp, slurry_reproduce::start), which begins with a transient of about ten
# revolutions. A run that survived is resumed with --resume instead, bit for bit.
#
# Stop the run first (SIGTERM: it writes a checkpoint of the step it has reached and exits),
# so that the pack and the time series end at the same step. SLURRY names the binary (default
# target/release/slurry). Write DEST/MANIFEST.md by hand: the leg's steps, revolutions,
# ⟨z_p⟩/H, binary, host. Fields, particle histories and checkpoints stay out of git.
set -eu
if [ $# -ne 2 ]; then sed -n "2,/^set -eu/p" "$0" | sed "\$d"; exit 2; fi
SLURRY=${SLURRY:-target/release/slurry}
src=$1 dest=$2
for f in manifest.json run/timeseries.csv run/particles.h5; do
  [ -f "$src/$f" ] || { echo "save-leg.sh: $src/$f is missing (not a reproduction's output directory?)" >&2; exit 1; }
done
mkdir -p "$dest"
cp "$src/manifest.json" "$dest/"
# The leg's own rows (the series before it is in the pack, and in the earlier legs' archives).
first=0
if [ -f "$src/run/legs.json" ]; then
  first=$(grep -o '"first_step": [0-9]*' "$src/run/legs.json" | tail -n 1 | grep -o '[0-9]*$')
fi
awk -F, -v first="$first" 'NR == 1 || $1 + 0 > first + 0 || (first == 0 && $1 == "0")' \
  "$src/run/timeseries.csv" > "$dest/timeseries.csv"
[ -f "$src/start.json" ] && cp "$src/start.json" "$dest/"
"$SLURRY" start-pack "$src" "$dest/start"
"$SLURRY" state-pack "$src/run" "$dest/state.h5"
du -sh "$dest" "$dest/start" "$dest/state.h5"
tail -n 1 "$dest/timeseries.csv" | cut -d, -f1,8
