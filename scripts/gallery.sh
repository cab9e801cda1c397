#!/usr/bin/env bash
# Regenerate the results gallery (results/gallery/) and the tables it is built
# from, with one command:
#
#     scripts/gallery.sh
#
# Needs a release build of cradle (made here) and python3 (standard library
# only). Sweeps run on the default backend (a hardware GPU if there is one,
# else the CPU); the outcomes are the same on both.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
C=./target/release/cradle
G=results/gallery
mkdir -p "$G"

# Mass × gap phase diagram of a 5-ball cradle (the README's main job).
$C sweep examples/mass_gap.toml --out results/mass_gap.csv
$C plot results/mass_gap.csv --x gap --y 'mass[2]' --z ejected --out "$G/mass_gap_ejected.png"
$C plot results/mass_gap.csv --x gap --y 'mass[2]' --z energy_last --out "$G/mass_gap_energy_last.png"

# Glue patterns × number of launched balls.
$C sweep examples/glue_launch.toml --out results/glue_launch.csv
$C plot results/glue_launch.csv --x launch.balls --y glue --z ejected --out "$G/glue_launch_ejected.png"
$C plot results/glue_launch.csv --x launch.balls --y glue --z energy_last --out "$G/glue_launch_energy_last.png"

# The seed's three scenes: Hertz, hard spheres, the seed's closure, the seed's numbers.
python3 scripts/seed_table.py --cradle "$C" > "$G/seed_scenes.md"

# A damped pendulum cradle drifting towards swinging together (trace not kept in git).
$C run examples/rocking.toml --trace "$G/rocking_trace.csv" --trace-dt 0.004 > "$G/rocking.txt"
$C plot --trace "$G/rocking_trace.csv" --out "$G/rocking.png" \
    --title "Rocking cradle: 5 balls on 0.2 m strings, restitution 0.97, 30 s"

# A 5-ball cradle, one ball in at 1 m/s: the collision in detail.
$C run cradle-1 --trace "$G/cradle1_trace.csv" > /dev/null
$C plot --trace "$G/cradle1_trace.csv" --out "$G/cradle1.png" \
    --title "cradle-1: one ball into four at 1 m/s (Hertz contacts)"

# Steps per swing of pendulum runs.
python3 scripts/pendulum_steps.py --cradle "$C" --out results/pendulum_steps.csv > "$G/pendulum_steps.md"
echo "gallery: $G"
