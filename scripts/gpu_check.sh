#!/bin/bash
# The one call for a lent GPU (issue #48): everything the GPU path is judged
# by, in about 6 minutes, every run under `timeout`, the table printed last
# and written with the raw logs where the device tool returns files ($OUT).
#
# Here, once (builds and copies everything; no device time):
#   bash scripts/device_prep.sh
# Then one device call, carrying .gl and .gpu, from the project's root:
#   bash .gpu/gpu_check.sh
# It stops at once (exit 3) when the adapter is not a hardware GPU, so no
# device time goes to timing lavapipe or the CPU twice.
#
# Workloads (each GPU table is compared with the CPU's: the largest relative
# difference of its numeric outcome columns and the rows whose status differs):
#   grid1000  10^6 five-ball cradles (scripts/grid.py 1000 1000): GPU f64 at
#             the default profile (twice: the first pays the shader builds;
#             four batches of 8,192 held at once, sharing each round's
#             dispatches: the stats say how many a round ran)
#             and at three other shapes (the scenes' constants copied
#             into private arrays as before, consts_from_params=false; a
#             batch of 32,768; 16,384 with 8 calls), GPU f32, the CPU on all
#             cores, the hard-sphere model on the CPU (the floor: no physics).
#   stress    examples/stress.toml (3,360 chains up to 64 balls), the GPU
#             capped at STRESS_CAP seconds; again with the wide kernel's
#             reductions through workgroup memory (subgroups=false) beside
#             the default's subgroup shuffles.
#   struck    1,000 struck chains of 1,000 beads (issue #30's target).
#   dimer     512 struck 100-bead dimer chains (8 radius ratios x 64 speeds).
#   damped    256 struck 300-bead chains with dashpots and air drag
#             (viscosity 0.5 N s/m, air drag 20/s; issue #45's damped kernel,
#             never timed on hardware before commit c968fea).
#             struck and dimer also on the chain kernel's global path
#             (CRADLE_GPU_PROFILE=hardware,chain_local=false: every chain's
#             velocities and forces in the storage buffer, as before the
#             workgroup-memory path), same binary, same call.
#   contract  issue #43's family (examples/chain_contract.rs: 20 chains at
#             tolerances 1e-4, 1e-6, 1e-8, the 30-bead sensitive one left out:
#             5.6 million steps at 1e-8) under the error control on the GPU
#             in f64 (~100 s on an H200; df64 took over 170 s for its first
#             tolerance there, CONTRACT_PRECISIONS="f64 df64" to try); its JSON
#             comes back in $OUT, for the reference here
#             (CONTRACT_ONLY=damped: only the chains whose name holds it):
#             scripts/chain_reference.py, chain_contract_table.py --backends.
# Environment: CAP (seconds per chain run, default 120), GRID_CAP (per grid1000
# run, default 45), STRESS_CAP (the GPU's stress run, default 60),
# PROFILES (the extra grid1000 profiles, ';'-separated), ALLOW_SOFTWARE=1
# (go on on lavapipe: a dry run of the script itself, with a small CAP),
# SHAPE_CAP (each extra grid1000 shape, default 25), SKIP (workloads left out,
# e.g. "struck dimer": a call that measures a change of the cradle path only).
# CHAIN_SHAPES (';'-separated profiles, e.g. "hardware,chain_wg=256"): the
# struck and dimer workloads once more on the GPU under each.
# SKIP takes workload prefixes or run names (e.g. "grid stress struck_cpu").
# DEADLINE (seconds from the start, default 450): no run is started or
# lets run past it less a minute kept for the table, so the table and the
# logs come back whatever a run takes.
# Every GPU run logs each batch's rounds (CRADLE_GPU_LOG=1) into its .log.
# CRADLE (default ./cradle, the binary device_prep.sh built): another
# binary, e.g. a baseline's, measured in the same call.
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
out=${OUT:-/tmp/gpu_check_out}
w=/tmp/gpu_check; rm -rf "$w"; mkdir -p "$w" "$out"
cd "$here"
for f in "$root"/.gl/*.deb; do dpkg -x "$f" / 2>/dev/null; done; ldconfig 2>/dev/null
export XDG_RUNTIME_DIR=/tmp WGPU_BACKEND=vulkan
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[ -f "$icd" ] && export VK_DRIVER_FILES=$icd
CAP=${CAP:-120}; GRID_CAP=${GRID_CAP:-45}; STRESS_CAP=${STRESS_CAP:-60}; SHAPE_CAP=${SHAPE_CAP:-25}
SKIP=${SKIP:-}; export CRADLE_GPU_LOG=1
CRADLE=${CRADLE:-./cradle}
DEADLINE=${DEADLINE:-450}; t0=$(date +%s)
# capped CAP: CAP, or less so as to end a minute before the deadline (0: no time left).
capped() {
  local left=$((DEADLINE - 60 - ($(date +%s) - t0)))
  [ "$left" -lt 5 ] && { echo 0; return; }
  [ "$1" -lt "$left" ] && echo "$1" || echo "$left"
}
PROFILES=${PROFILES:-"hardware,consts_from_params=false;hardware,batch=32768;hardware,batch=16384,calls=8"}
table=$w/table.md
log() { echo "$*" | tee -a "$w/check.log" "$out/check.log"; }

{ nvidia-smi; nvidia-smi -q -d CLOCK,PERFORMANCE,POWER; } >"$w/nvidia-smi.txt" 2>&1
nvidia-smi -L 2>/dev/null | tee -a "$w/check.log"
log "cores: $(nproc); $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"
# The commit the binary was built from, as device_prep.sh recorded it
# (with "+ uncommitted changes" when the tree was not clean then).
log "commit: $(cat "$here/COMMIT" 2>/dev/null || (cd "$root" && git rev-parse --short HEAD 2>/dev/null) || echo unknown)"

# The adapter first: a tiny sweep on --backend gpu, its sidecar's adapter.
timeout -k 5 60 "$CRADLE" sweep grid100.toml --out "$w/probe.csv" --backend gpu >"$w/probe.log" 2>&1
adapter=$(python3 -c "import json; print(json.load(open('$w/probe.csv.json')).get('adapter', ''))" 2>/dev/null)
log "adapter: ${adapter:-none}"
case "${ALLOW_SOFTWARE:-0}:$adapter" in
  *:|0:*Cpu*|0:*llvmpipe*)
    log "not a hardware GPU: stopping (see $w/probe.log)"; cat "$w/probe.log"
    tar czf "$out/gpu_check.tar.gz" -C /tmp gpu_check; exit 3 ;;
esac

cat >"$w/struck.toml" <<'T'
[scene]
balls = 1000
radius = 0.005
[scene.launch]
balls = 1
velocity = 0.1
[scene.probes]
beads = [250, 750]
[[axis]]
param = "launch.velocity"
logspace = [0.01, 1.0, 1000]
T
cat >"$w/dimer.toml" <<'T'
[scene]
balls = 100
radius = 0.005
[scene.pattern]
radius = [0.005, 0.0035]
[scene.launch]
balls = 1
velocity = 0.1
[scene.probes]
beads = [20, 80]
[[axis]]
param = "pattern.radius[1]"
linspace = [0.002, 0.005, 8]
[[axis]]
param = "launch.velocity"
logspace = [0.01, 1.0, 64]
T
cat >"$w/damped.toml" <<'T'
[scene]
balls = 300
radius = 0.005
[scene.launch]
balls = 1
velocity = 0.1
[scene.probes]
beads = [75, 225]
[scene.damping]
viscosity = 0.5
air_drag = 20.0
[[axis]]
param = "launch.velocity"
logspace = [0.01, 1.0, 256]
T
cp grid1000.toml stress.toml "$w/"

# run NAME CAP PROFILE ARGS...: one `cradle` call under `timeout`; its wall
# time (or "> CAP s (capped)") and the sidecar's GPU counters into $w/NAME.*.
run() {
  local name=$1 cap=$2 prof=$3; shift 3
  local s e rc
  for k in $SKIP; do case $name in "$k" | "$k"_*) return ;; esac; done
  cap=$(capped "$cap")
  if [ "$cap" = 0 ]; then
    echo "not run (deadline)" >"$w/$name.wall"; log "$name: not run (deadline)"; return
  fi
  s=$(date +%s.%N)
  if [ -n "$prof" ]; then
    CRADLE_GPU_PROFILE=$prof timeout -k 5 "$cap" "$CRADLE" "$@" >"$w/$name.log" 2>&1; rc=$?
  else
    timeout -k 5 "$cap" "$CRADLE" "$@" >"$w/$name.log" 2>&1; rc=$?
  fi
  e=$(python3 -c "print(f'{$(date +%s.%N)-$s:.2f}')")
  case $rc in
    0) echo "$e" >"$w/$name.wall" ;;
    124|137) echo "> $cap (capped)" >"$w/$name.wall" ;;
    *) echo "failed (exit $rc)" >"$w/$name.wall" ;;
  esac
  log "$(printf '%-22s %-14s %s' "$name" "$(cat "$w/$name.wall")" "$(grep -v '^cradle: gpu batch' "$w/$name.log" | tail -1)")"
}

g=grid1000.toml
run grid_gpu_f64_cold "$GRID_CAP" "" sweep $g --out $w/grid_gpu_f64_cold.csv --backend gpu --precision f64
run grid_gpu_f64      "$GRID_CAP" "" sweep $g --out $w/grid_gpu_f64.csv --backend gpu --precision f64
i=0; IFS=';' read -ra extra <<<"$PROFILES"
for p in "${extra[@]}"; do
  i=$((i + 1)); echo "$p" >"$w/grid_gpu_f64_shape$i.profile"
  run "grid_gpu_f64_shape$i" "$SHAPE_CAP" "$p" sweep $g --out "$w/grid_gpu_f64_shape$i.csv" --backend gpu --precision f64
done
run grid_gpu_f32      "$GRID_CAP" "" sweep $g --out $w/grid_gpu_f32.csv --backend gpu --precision f32
run grid_cpu          "$GRID_CAP" "" sweep $g --out $w/grid_cpu.csv --backend cpu
run grid_hard_sphere  "$GRID_CAP" "" sweep $g --out $w/grid_hard_sphere.csv --backend cpu --model hard-sphere
run struck_gpu        "$CAP" "" sweep $w/struck.toml --out $w/struck_gpu.csv --backend gpu
run struck_gpu_global "$CAP" "hardware,chain_local=false" sweep $w/struck.toml --out $w/struck_gpu_global.csv --backend gpu
run struck_cpu        "$CAP" "" sweep $w/struck.toml --out $w/struck_cpu.csv --backend cpu
run dimer_gpu         "$CAP" "" sweep $w/dimer.toml --out $w/dimer_gpu.csv --backend gpu
run dimer_gpu_global  "$CAP" "hardware,chain_local=false" sweep $w/dimer.toml --out $w/dimer_gpu_global.csv --backend gpu
run dimer_cpu         "$CAP" "" sweep $w/dimer.toml --out $w/dimer_cpu.csv --backend cpu
run damped_gpu        "$CAP" "" sweep $w/damped.toml --out $w/damped_gpu.csv --backend gpu
run damped_cpu        "$CAP" "" sweep $w/damped.toml --out $w/damped_cpu.csv --backend cpu
i=0; IFS=';' read -ra cshapes <<<"${CHAIN_SHAPES:-}"
for p in "${cshapes[@]}"; do
  i=$((i + 1)); echo "$p" >"$w/chain_shape$i.profile"
  run "struck_shape$i" "$CAP" "$p" sweep $w/struck.toml --out "$w/struck_shape$i.csv" --backend gpu
  run "dimer_shape$i" "$CAP" "$p" sweep $w/dimer.toml --out "$w/dimer_shape$i.csv" --backend gpu
done
run stress_gpu  "$STRESS_CAP" "" sweep stress.toml --out $w/stress_gpu.csv --backend gpu --precision f64
run stress_gpu_tree "$STRESS_CAP" "hardware,subgroups=false" sweep stress.toml --out $w/stress_gpu_tree.csv --backend gpu --precision f64
run stress_cpu        "$CAP" "" sweep stress.toml --out $w/stress_cpu.csv --backend cpu
if [ -x ./chain_contract ] && ! [[ " $SKIP " == *" contract "* ]]; then
  for p in ${CONTRACT_PRECISIONS:-f64}; do
    c=$(capped "$CAP"); [ "$c" = 0 ] && { log "contract_gpu_$p: not run (deadline)"; continue; }
    s=$(date +%s.%N)
    timeout -k 5 "$c" ./chain_contract "$w/contract_$p.json" ${CONTRACT_ONLY:-} --skip "sensitive: 30" --backend gpu --precision $p >"$w/contract_$p.log" 2>&1
    log "contract_gpu_$p       exit $? in $(python3 -c "print(f'{$(date +%s.%N)-$s:.2f}')") s: $(tail -2 "$w/contract_$p.log" | tr '\n' ' ')"
    [ -f "$w/contract_$p.json" ] && gzip -c "$w/contract_$p.json" >"$out/contract_$p.json.gz"
  done
fi

python3 - "$w" "$adapter" >"$table" <<'PY'
import csv, filecmp, json, math, os, sys
w, adapter = sys.argv[1], sys.argv[2]
def wall(n):
    p = f"{w}/{n}.wall"
    return open(p).read().strip() if os.path.exists(p) else "not run"
def secs(n):
    try: return float(wall(n))
    except ValueError: return None
def gpu_stats(n):
    try: g = json.load(open(f"{w}/{n}.csv.json")).get("stages_s", {})
    except Exception: return ""
    d = g.get("gpu", {})
    if not d: return ""
    return (f"{d.get('dispatches', 0)} dispatches, {d.get('rounds', 0)} rounds, "
            + (f"{d['batches_per_round']:.2f} batches a round (at most {d['most_batches_in_a_round']}), "
               if d.get('most_batches_in_a_round') else "")
            + f"in flight {d.get('in_flight_fraction', 0):.2f}, on cpu {d.get('scenes_on_cpu', 0)}"
            + (f"; host s: packing {d.get('packing', 0):.2f}, unpacking {d.get('unpacking', 0):.2f}, "
               f"compiling {d['compiling']:.2f}" if 'compiling' in d else ""))
done = {}  # tables already compared: a table with the same bytes reuses the result
def diff(a, b):
    """Largest difference of a numeric outcome column relative to that column's
    scale (its largest magnitude in either table), and the rows whose status
    differs. Left out: the round-off columns (*_error) and columns whose scale
    is under 1e-12 (zeros up to round-off: a struck chain's final velocities
    behind the wave, its energy left behind). A GPU table byte-identical to
    one compared before (outputs do not depend on the profile) is not read
    again: 10^6 rows take ~15 s of Python."""
    pa, pb = f"{w}/{a}.csv", f"{w}/{b}.csv"
    if not (os.path.exists(pa) and os.path.exists(pb)):
        return "no table"
    for prior, said in done.items():
        if prior[1] == pb and filecmp.cmp(prior[0], pa, shallow=False):
            return said
    ra, rb = csv.reader(open(pa)), csv.reader(open(pb))
    ha, hb = next(ra), next(rb)
    cols = [(i, hb.index(k), k) for i, k in enumerate(ha)
            if k not in ("id", "status") and not k.endswith("_error") and k in hb]
    sa, sb = ha.index("status") if "status" in ha else None, hb.index("status") if "status" in hb else None
    scale = {k: 0.0 for _, _, k in cols}; dmax = dict(scale)
    rows = status = 0
    for x, y in zip(ra, rb):
        rows += 1
        if sa is not None and sb is not None and x[sa] != y[sb]:
            status += 1
        for i, j, k in cols:
            try: u, v = float(x[i]), float(y[j])
            except ValueError: continue
            if math.isfinite(u) and math.isfinite(v):
                m = max(abs(u), abs(v))
                if m > scale[k]: scale[k] = m
                if abs(u - v) > dmax[k]: dmax[k] = abs(u - v)
    worst, col = 0.0, ""
    for k in scale:
        if scale[k] > 1e-12 and dmax[k] / scale[k] > worst:
            worst, col = dmax[k] / scale[k], k
    said = f"{rows} rows; max diff / column scale {worst:.1e} ({col or 'bit-identical'}); status differs {status}"
    done[(pa, pb)] = said
    return said
def speed(g, c):
    a, b = secs(g), secs(c)
    return f"{b / a:.2f}x" if a and b else "n/a"
rows = [
    ("grid1000 GPU f64 (cold: shader builds)", "grid_gpu_f64_cold", "grid_cpu"),
    ("grid1000 GPU f64", "grid_gpu_f64", "grid_cpu"),
]
i = 1
while os.path.exists(f"{w}/grid_gpu_f64_shape{i}.profile"):
    rows.append((f"grid1000 GPU f64 [{open(f'{w}/grid_gpu_f64_shape{i}.profile').read().strip()}]",
                 f"grid_gpu_f64_shape{i}", "grid_cpu")); i += 1
rows += [
    ("grid1000 GPU f32", "grid_gpu_f32", "grid_cpu"),
    ("grid1000 CPU, all cores", "grid_cpu", None),
    ("grid1000 hard-sphere CPU (floor)", "grid_hard_sphere", None),
    ("struck 1,000 x 1,000 beads GPU", "struck_gpu", "struck_cpu"),
    ("struck 1,000 x 1,000 beads GPU, global path", "struck_gpu_global", "struck_cpu"),
    ("struck 1,000 x 1,000 beads CPU", "struck_cpu", None),
    ("dimer 512 x 100 beads GPU", "dimer_gpu", "dimer_cpu"),
    ("dimer 512 x 100 beads GPU, global path", "dimer_gpu_global", "dimer_cpu"),
    ("dimer 512 x 100 beads CPU", "dimer_cpu", None),
    ("damped 256 x 300 beads GPU", "damped_gpu", "damped_cpu"),
    ("damped 256 x 300 beads CPU", "damped_cpu", None),
]
i = 1
while os.path.exists(f"{w}/chain_shape{i}.profile"):
    p = open(f"{w}/chain_shape{i}.profile").read().strip()
    rows.append((f"struck GPU [{p}]", f"struck_shape{i}", "struck_cpu"))
    rows.append((f"dimer GPU [{p}]", f"dimer_shape{i}", "dimer_cpu"))
    i += 1
rows += [
    ("stress.toml GPU f64", "stress_gpu", "stress_cpu"),
    ("stress.toml GPU f64, reductions by the tree (subgroups=false)", "stress_gpu_tree", "stress_cpu"),
    ("stress.toml CPU", "stress_cpu", None),
]
print(f"adapter: {adapter}\n")
print("| workload | wall (s) | vs CPU | difference from the CPU's table | GPU counters |")
print("|---|---|---|---|---|")
for label, n, c in rows:
    print(f"| {label} | {wall(n)} | {speed(n, c) if c else ''} | {diff(n, c) if c else ''} | {gpu_stats(n)} |")
PY
cp "$table" "$out/gpu_check.md"
tar czf "$out/gpu_check.tar.gz" -C /tmp --exclude='grid_*.csv' --exclude='stress_*.csv' --exclude='*.partial' --exclude='probe.csv' gpu_check
echo; cat "$table"
