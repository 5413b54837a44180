#!/usr/bin/env bash
# The device backend on this machine's GPU, in one command of a few minutes: what the machine
# has, the device tests against the CPU, the verification cases that run on the device
# (`slurry-verify --device gpu`, the CPU's tolerances), and the fluid step's speed against the
# device's copy bandwidth, measured in the same run. Results go to OUT (default
# target/device-check/): device-check.json (the machine, the verdicts, times), verify-gpu.json,
# bench-device.json (one row per grid and collision model, CPU and device, with the copy
# bandwidth), and the logs.
#
# Usage: benches/scripts/device-check.sh [OUT]
#   from the repository root. With cargo, it builds what it runs (release). Without cargo (a
#   machine that cannot reach crates.io), it uses prebuilt binaries: SLURRY_BIN (default
#   target/release/slurry), SLURRY_VERIFY_BIN (default target/release/slurry-verify) and, for
#   the tests, every executable target/release/deps/device_*
#   (copy them with the tree; `cargo test --release --no-run -p slurry --test device_fluid`,
#   one `--test` per tests/device_*.rs, builds them).
# Environment: SIZES (default "128 256 251x251x240"), REPS (default 5), WORKGROUP (default 64).
# Needs the Vulkan loader (libvulkan1) and the GPU's Vulkan driver (NVIDIA's ships its ICD with
# the driver); `cargo xtask setup` installs the loader and Mesa's drivers on Debian.
set -uo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cd "$root"
out=${1:-target/device-check}
mkdir -p "$out"
sizes=${SIZES:-128 256 251x251x240}
reps=${REPS:-5}
wg=${WORKGROUP:-64}
t0=$(date +%s)
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}

json_escape() { python3 -c 'import json,sys; print(json.dumps(sys.stdin.read().strip()))' 2>/dev/null || echo '""'; }

gpu=$( (nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader 2>/dev/null || echo "no nvidia-smi") | head -n 4)
cpu=$(grep -m1 'model name' /proc/cpuinfo 2>/dev/null | cut -d: -f2- | sed 's/^ *//')
if ! ldconfig -p 2>/dev/null | grep -q 'libvulkan.so.1'; then
  echo "device-check: the Vulkan loader (libvulkan.so.1) is missing: apt-get install libvulkan1 (or cargo xtask setup)" >&2
fi

# Build, or find the prebuilt binaries.
tests=()
if command -v cargo >/dev/null; then
  echo "== build (release) =="
  cargo build --release -p slurry-reproduce -p slurry-verification 2>&1 | tail -n 2
  targets=()
  for f in tests/device_*.rs; do targets+=(--test "$(basename "$f" .rs)"); done
  mapfile -t tests < <(cargo test --release --no-run -p slurry "${targets[@]}" \
    --message-format=json 2>/dev/null | python3 -c '
import json, sys
for line in sys.stdin:
    try: m = json.loads(line)
    except ValueError: continue
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["kind"] == ["test"]:
        print(m["executable"])')
  slurry=target/release/slurry
  verify=target/release/slurry-verify
else
  slurry=${SLURRY_BIN:-target/release/slurry}
  verify=${SLURRY_VERIFY_BIN:-target/release/slurry-verify}
  mapfile -t tests < <(find target/release/deps -maxdepth 1 -type f -executable -name 'device_*' 2>/dev/null | sort)
fi
[ -x "$slurry" ] || { echo "device-check: no slurry binary at $slurry" >&2; exit 1; }

# The device tests (each against the CPU on this machine).
echo "== device tests =="
verdicts=""
for t in "${tests[@]}"; do
  name=$(basename "$t" | sed 's/-[0-9a-f]*$//')
  s=$(date +%s)
  if "$t" --test-threads 1 >"$out/test-$name.log" 2>&1; then v=pass; else v=FAIL; fi
  line=$(grep -E '^test result' "$out/test-$name.log" | tail -n 1)
  echo "$name: $v ($line, $(( $(date +%s) - s )) s)"
  verdicts+="${verdicts:+,}{\"test\":\"$name\",\"verdict\":\"$v\",\"summary\":$(echo "$line" | json_escape)}"
done
[ ${#tests[@]} -gt 0 ] || echo "device-check: no device test binaries found (build them with cargo, see the header)" >&2

# The verification cases that run on the device, with the CPU's tolerances and reference
# tables (the tables read from this checkout).
echo "== verification on the device (quick tier) =="
verify_rc=127
if [ -x "$verify" ]; then
  SLURRY_WORKSPACE=$PWD "$verify" --device gpu --tier quick --report "$out/verify-gpu.json" >"$out/verify-gpu.log" 2>&1
  verify_rc=$?
  grep -E '^\([a-z_]+ in|passed, ' "$out/verify-gpu.log"
else
  echo "device-check: no slurry-verify binary at $verify" >&2
fi

# The fluid step: CPU (all cores) and device in the same run, with the copy bandwidth.
echo "== bench =="
args=()
args+=(--sizes "$(echo $sizes | tr " " ",")")
"$slurry" bench --device gpu "${args[@]}" --precisions f32 --collisions bgk,trt --threads "$(nproc)" \
  --reps "$reps" --seconds 1 --workgroup "$wg" --json "$out/bench-device.json" 2>&1 | tee "$out/bench.log"
bench_rc=${PIPESTATUS[0]}

cat >"$out/device-check.json" <<EOF
{
  "gpu": $(echo "$gpu" | json_escape),
  "cpu": $(echo "$cpu" | json_escape),
  "cores": $(nproc),
  "revision": $(git rev-parse --short HEAD 2>/dev/null | json_escape),
  "tests": [${verdicts}],
  "verify_exit_status": ${verify_rc},
  "verify": "verify-gpu.json",
  "bench_exit_status": ${bench_rc},
  "bench": "bench-device.json",
  "seconds": $(( $(date +%s) - t0 ))
}
EOF
echo "device-check: wrote $out/device-check.json and $out/bench-device.json in $(( $(date +%s) - t0 )) s"
