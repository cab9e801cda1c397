#!/usr/bin/env bash
# Pin the bytes of every output a refactor must not change: prints one line
# `NAME SHA256` per output, in a fixed order. Run it before and after a
# change and diff the two (`diff <(bash scripts/pin_outputs.sh) results/pins.txt`).
#
#   bash scripts/pin_outputs.sh [CRADLE] > pins.txt     # CRADLE: default target/release/cradle
#
# With a GPU adapter (Mesa lavapipe here: XDG_RUNTIME_DIR=/tmp WGPU_BACKEND=vulkan),
# grid100 is also pinned on the GPU backend in f64, f32 and df64; without one
# those lines say `skipped`. ~1 min on the project's 2-core VM (stress.toml
# is most of it). Sidecars hold wall times, so they are not pinned; their
# fingerprint's keys are checked by the tests.
set -euo pipefail
cd "$(dirname "$0")/.."
C="${1:-target/release/cradle}"
C="$(cd "$(dirname "$C")" && pwd)/$(basename "$C")"
T="$(mktemp -d)"
trap 'rm -rf "$T"' EXIT
ex="$PWD/examples"

pin() { printf '%s %s\n' "$1" "$(sha256sum "$2" | cut -d' ' -f1)"; }
q() { "$C" "$@" 2>/dev/null; }

q sweep "$ex/grid100.toml" --backend cpu --out "$T/grid100.csv"
pin grid100.csv "$T/grid100.csv"
q sweep "$ex/grid100.toml" --backend cpu --out "$T/grid100.parquet"
pin grid100.parquet "$T/grid100.parquet"
q sweep "$ex/grid100.toml" --backend cpu --precision f32 --out "$T/grid100_f32.csv"
pin grid100_f32_cpu.csv "$T/grid100_f32.csv"
q sweep "$ex/grid100.toml" --backend cpu --precision df64 --tolerance 1e-6 --out "$T/grid100_df64.csv"
pin grid100_df64_cpu.csv "$T/grid100_df64.csv"
q sweep "$ex/grid100.toml" --backend cpu --error-estimate --method yoshida4 --out "$T/grid100_est.csv"
pin grid100_yoshida4_estimate.csv "$T/grid100_est.csv"
for m in hard-sphere closure; do
    q sweep "$ex/grid100.toml" --backend cpu --model $m --out "$T/grid100_$m.csv"
    pin "grid100_$m.csv" "$T/grid100_$m.csv"
done
for k in 1 2 3; do
    q sweep "$ex/grid100.toml" --backend cpu --shard $k/3 --out "$T/part$k.csv"
    q sweep "$ex/grid100.toml" --backend cpu --shard $k/3 --out "$T/part$k.parquet"
    pin "grid100_shard$k.csv" "$T/part$k.csv"
done
q merge "$T"/part{1,2,3}.csv --out "$T/merged.csv"
pin grid100_merged.csv "$T/merged.csv"
q merge "$T"/part{1,2,3}.parquet --out "$T/merged.parquet"
pin grid100_merged.parquet "$T/merged.parquet"

q sweep "$ex/mass_gap.toml" --backend cpu --out "$T/mass_gap.csv"
pin mass_gap.csv "$T/mass_gap.csv"
q sweep "$ex/glue_launch.toml" --backend cpu --out "$T/glue_launch.csv"
pin glue_launch.csv "$T/glue_launch.csv"
q run "$ex/rocking.toml" --format csv >"$T/rocking.csv"
pin rocking.csv "$T/rocking.csv"
q sweep "$ex/stress.toml" --backend cpu --out "$T/stress.csv"
pin stress.csv "$T/stress.csv"

# Granular chains: a dimer against a wall with dashpots, Hunt–Crossley
# contacts and air drag, swept over the viscosity and the restitution, in
# f64 with kahanli6 and with yoshida4 (a substep back in time), and in df64;
# and one chain pushed every way of issue #45 (a piston, a drive, gravity,
# dashpots between precompressed walls).
cat >"$T/chain.toml" <<'EOF'
balls = 40
radius = 0.005
[pattern]
radius = [0.005, 0.0035]
[walls]
right = true
[launch]
balls = 1
velocity = 0.1
[probes]
beads = [10, 30]
[damping]
viscosity = 0.5
air_drag = 20.0
[stop]
duration = 2e-4
EOF
cat >"$T/chains.toml" <<'EOF'
scene = "chain.toml"
[[axis]]
param = "damping.viscosity"
values = [0.0, 0.5, 5.0]
[[axis]]
param = "damping.restitution"
values = [0.95, 0.5]
EOF
q sweep "$T/chains.toml" --backend cpu --tolerance 1e-5 --out "$T/chains.csv"
pin chains_damped.csv "$T/chains.csv"
q sweep "$T/chains.toml" --backend cpu --tolerance 1e-5 --method yoshida4 --out "$T/chains_y4.csv"
pin chains_damped_yoshida4.csv "$T/chains_y4.csv"
q sweep "$T/chains.toml" --backend cpu --tolerance 1e-4 --precision df64 --out "$T/chains_df64.csv"
pin chains_damped_df64.csv "$T/chains_df64.csv"
cat >"$T/pushed.toml" <<'EOF'
balls = 40
radius = 0.005
[walls]
left = true
right = true
precompression = 2.0
[piston]
velocity = 0.05
[drive]
bead = 20
force = 0.05
frequency = 20000.0
[gravity]
g = 9.80665
[damping]
viscosity = 1.0
[probes]
beads = [5, 30]
[stop]
duration = 3e-4
EOF
q run "$T/pushed.toml" --format csv >"$T/pushed.csv"
pin chain_pushed.csv "$T/pushed.csv"

# A refined sweep, its Parquet twin, and its fill.
cat >"$T/refine.toml" <<'EOF'
[scene]
balls = 5
velocity = [1.0, 0, 0, 0, 0]
[[axis]]
param = "mass[2]"
logspace = [0.00642, 0.642, 33]
[[axis]]
param = "gap"
linspace = [0.0, 2e-5, 33]
[refine]
column = "ejected"
stride = 4
EOF
q sweep "$T/refine.toml" --backend cpu --out "$T/refined.csv"
pin refined.csv "$T/refined.csv"
q sweep "$T/refine.toml" --backend cpu --out "$T/refined.parquet"
pin refined.parquet "$T/refined.parquet"
q fill "$T/refined.csv" --out "$T/filled.csv"
pin filled.csv "$T/filled.csv"

# One scene: the table, the CSV row, a trace; the plots.
q run cradle-1 >"$T/run.txt"
pin run_cradle-1.txt "$T/run.txt"
q run seed-glued-pair-into-three --format csv >"$T/run.csv"
pin run_glued.csv "$T/run.csv"
q run cradle-1 --trace "$T/trace.csv" --trace-dt 1e-6 >/dev/null
pin trace_cradle-1.csv "$T/trace.csv"
q plot "$T/grid100.csv" --x gap --y 'mass[2]' --z ejected --out "$T/map.svg"
pin plot_map.svg "$T/map.svg"
q plot --trace "$T/trace.csv" --out "$T/trace.svg"
pin plot_trace.svg "$T/trace.svg"
q slurm "$ex/grid100.toml" --shards 4 --dir "$T/slurm" --cradle /opt/cradle --time 00:10:00 >/dev/null
sed "s|$T|T|g; s|$PWD|REPO|g" "$T/slurm/array.sbatch" >"$T/array.sbatch"
pin slurm_array.sbatch "$T/array.sbatch"

# The GPU backend (lavapipe in CI): grid100 in three precisions.
for p in f64 f32 df64; do
    if q sweep "$ex/grid100.toml" --backend gpu --precision $p --out "$T/gpu_$p.csv"; then
        pin "grid100_gpu_$p.csv" "$T/gpu_$p.csv"
    else
        echo "grid100_gpu_$p.csv skipped"
    fi
done
