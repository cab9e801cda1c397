#!/bin/bash
# Tune the GPU profile on a lent GPU machine without rebuilding: grid1000 (and
# stress.toml) under several CRADLE_GPU_PROFILE settings, each with its wall
# time and what the sidecar says the device did (stages_s.gpu). Copy it into
# .gpu/ beside the stripped `cradle`, grid1000.toml and stress.toml (see
# scripts/gpu/README.md) and run `bash .gpu/gpu_tune.sh [PROFILE ...]`.
# Outputs do not depend on the profile: every table is compared to the first
# of its workload and precision. Last, grid1000 in df64 (pairs of f32).
cd "$(dirname "$0")"
for f in ../.gl/*.deb; do dpkg -x "$f" /; done 2>/dev/null; ldconfig 2>/dev/null
export XDG_RUNTIME_DIR=/tmp
nvidia-smi -L 2>/dev/null; echo "cores: $(nproc)"
profiles=("$@")
[ ${#profiles[@]} -eq 0 ] && profiles=(
  hardware
  "hardware,scenes_per_worker=1"
  "hardware,scenes_per_worker=2,calls=8"
  "hardware,batch=65536,calls=2,scenes_per_worker=2"
  "hardware,timed=false,rounds=4096"
  "hardware,wide_above=none"
  "hardware,wide_above=8"
  "hardware,wide_above=32"
  "hardware,wide_above=none,cpu_above=32"
)
run() {  # run WORKLOAD PRECISION PROFILE
  local out=/tmp/tune-$1-$2.csv s w
  s=$(date +%s.%N)
  CRADLE_GPU_PROFILE=$3 ./cradle sweep "$1.toml" --out "$out" --backend gpu --precision "$2" >/tmp/tune.log 2>&1 \
    || { echo "$1 $2 [$3] FAILED: $(tail -2 /tmp/tune.log)"; return; }
  w=$(python3 -c "print($(date +%s.%N)-$s)")
  python3 - "$out" "$1" "$2" "$3" "$w" <<'PY'
import json, sys, os, filecmp
out, work, prec, prof, wall = sys.argv[1:6]
g = json.load(open(out + ".json"))["stages_s"].get("gpu", {})
first = f"/tmp/tune-first-{work}-{prec}.csv"
if not os.path.exists(first):
    os.rename(out, first); same = "first"
else:
    same = "same bytes" if filecmp.cmp(out, first, shallow=False) else "DIFFERENT BYTES"
print(f"{work:9} {prec} {float(wall):8.3f} s  dispatches {g.get('dispatches', 0):>8}  rounds {g.get('rounds', 0):>7}"
      f"  in flight {g.get('in_flight_fraction', 0):.2f}  on cpu {g.get('scenes_on_cpu', 0):>5}  {same}  [{prof}]")
PY
}
rm -f /tmp/tune-first-*
for p in "${profiles[@]}"; do
  run grid1000 f64 "$p"; run grid1000 f32 "$p"
done
# df64 (f32 pairs) against f64 and f32 on the first profile: its cost where f64 is not slow.
run grid1000 df64 "${profiles[0]}"
for p in "${profiles[@]}"; do run stress f64 "$p"; done
