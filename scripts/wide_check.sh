#!/bin/bash
# The kernel with a workgroup per scene (shaders/cradle/wide.wgsl)
# against the CPU backend and the serial kernel, byte for byte:
#   1. grid100 (5 balls) in f64, f32 and df64 with every chain wide
#      (CRADLE_GPU_PROFILE=software,wide_above=1) against the serial kernel;
#   2. stress.toml's 2–16-ball chains (2,688 scenes), every chain wide,
#      against the CPU backend;
#   3. a 33/64-ball slice of stress.toml (96 scenes: 3 masses × 2 speeds ×
#      2 moduli × 4 gaps) on the hardware profile (chains above 16 bodies
#      wide) against the CPU backend.
# Needs a GPU adapter (lavapipe will do: XDG_RUNTIME_DIR=/tmp
# WGPU_BACKEND=vulkan) and `cargo build --release`. Prints one line per check.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cradle=${CRADLE_BIN:-$root/target/release/cradle}
grid=${GRID100:-$root/examples/grid100.toml}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
sweep() { # OUT PROFILE ARGS...
  local out=$1 prof=$2
  shift 2
  local s=$SECONDS
  CRADLE_GPU_PROFILE=$prof "$cradle" sweep "$@" --out "$out" >"$tmp/log" 2>&1 ||
    { cat "$tmp/log"; exit 1; }
  echo $((SECONDS - s))
}
same() { cmp -s "$1" "$2" && echo "same bytes" || echo "DIFFERENT BYTES"; }
for p in f64 f32 df64; do
  ts=$(sweep "$tmp/serial-$p.csv" software "$grid" --backend gpu --precision "$p")
  tw=$(sweep "$tmp/wide-$p.csv" software,wide_above=1 "$grid" --backend gpu --precision "$p")
  echo "grid100 $p: wide ($tw s) vs serial kernel ($ts s): $(same "$tmp/serial-$p.csv" "$tmp/wide-$p.csv")"
done
sed 's/values = \[2, 3, 8, 16, 64\]/values = [2, 3, 8, 16]/' "$root/examples/stress.toml" >"$tmp/short.toml"
sed -e 's/values = \[2, 3, 8, 16, 64\]/values = [33, 64]/' \
  -e 's/64.22266231947886, 7\]/64.22266231947886, 3]/' \
  -e 's/\[1e-4, 10.0, 6\]/[1e-4, 10.0, 2]/' \
  -e 's/\[1e7, 1e12, 4\]/[1e7, 1e12, 2]/' "$root/examples/stress.toml" >"$tmp/long.toml"
tc=$(sweep "$tmp/short-cpu.csv" software "$tmp/short.toml" --backend cpu)
tw=$(sweep "$tmp/short-wide.csv" software,wide_above=1 "$tmp/short.toml" --backend gpu)
echo "stress 2-16 balls (2,688): wide ($tw s) vs CPU backend ($tc s): $(same "$tmp/short-cpu.csv" "$tmp/short-wide.csv")"
tc=$(sweep "$tmp/long-cpu.csv" software "$tmp/long.toml" --backend cpu)
tw=$(sweep "$tmp/long-wide.csv" hardware "$tmp/long.toml" --backend gpu)
gpu=$(python3 -c "import json,sys; g=json.load(open(sys.argv[1]))['stages_s']['gpu']; print(g['dispatches'], 'dispatches in', g['rounds'], 'rounds')" "$tmp/long-wide.csv.json")
echo "stress 33/64 balls (96): hardware profile, wide ($tw s, $gpu) vs CPU backend ($tc s): $(same "$tmp/long-cpu.csv" "$tmp/long-wide.csv")"
