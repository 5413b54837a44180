#!/usr/bin/env bash
# archive.sh RUN_OUT DEST : copy a finished reproduction (the --out directory of `slurry
# reproduce`) into the checkout's archive, e.g. reproduce/CASE/runs/DATE-sSCALE/: manifest,
# report, statistics, reproduce.json, the run's summary.json and timeseries.csv, start.json
# (a run started with --start-from), the PNG figures (each checked under 300 KB), and the
# run's start pack in DEST/start/ (`slurry start-pack`: its last frames at a blade position,
# under 1 MB, so that `--start-from DEST/start` works once RUN_OUT is gone), and the state pack
# of its last checkpoint in DEST/state.h5 (`slurry state-pack`: 4 MB at s = 1/4, so that
# `--start-from DEST/state.h5` continues the run itself, as one run: the pack carries its time
# series and legs; LABEL names it, default RUN_OUT; skipped with NO_STATE=1). Fields, particle
# histories and checkpoints stay out of git. SLURRY names the binary (default
# target/release/slurry). Write the archive's MANIFEST.md by hand: what the run shows, its
# sessions, its host.
set -eu
if [ $# -ne 2 ]; then sed -n "2,/^set -eu/p" "$0" | sed "\$d"; exit 2; fi
SLURRY=${SLURRY:-target/release/slurry}
src=$1 dest=$2
for f in manifest.json report.md reproduce.json statistics.json statistics.h5 run/summary.json run/timeseries.csv; do
  [ -f "$src/$f" ] || { echo "archive.sh: $src/$f is missing (not a finished reproduction?)" >&2; exit 1; }
done
for p in "$src"/*.png; do
  s=$(stat -c %s "$p")
  if [ "$s" -gt 300000 ]; then echo "archive.sh: $p is $s bytes, over 300 KB" >&2; exit 1; fi
done
mkdir -p "$dest"
for f in manifest.json report.md reproduce.json statistics.json statistics.h5; do cp "$src/$f" "$dest/"; done
cp "$src/run/summary.json" "$src/run/timeseries.csv" "$dest/"
# A run started from another run's particles (--start-from) records that start.
[ -f "$src/start.json" ] && cp "$src/start.json" "$dest/"
cp "$src"/*.png "$dest/"
"$SLURRY" start-pack "$src" "$dest/start"
[ "${NO_STATE:-0}" = 1 ] || "$SLURRY" state-pack "$src/run" "$dest/state.h5" --label "${LABEL:-$src}"
ls -la "$dest"
