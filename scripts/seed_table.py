#!/usr/bin/env python3
"""The seed's three scenes as one markdown table: Hertz (the engine), hard
spheres, the seed's closure model and the numbers the seed quotes, each with
its kinetic-energy balance (final / initial) and momentum balance.

    python3 scripts/seed_table.py [--cradle ./target/release/cradle] > results/gallery/seed_scenes.md

Only the Python standard library is needed.
"""
import argparse
import csv
import io
import math
import subprocess

G = 9.80665
# (scene, ball masses in units of m, initial velocities, what the seed quotes)
V2 = math.sqrt(2 * G * 0.05)
SCENES = [
    ("seed-two-lifted", [1] * 5, [V2, V2, 0, 0, 0],
     ("§2: two balls out at √(2gh)", [0, 0, 0, V2, V2])),
    ("seed-glued-pair-into-one", [1] * 3, [1.0, 1.0, 0],
     ("§3.2: 1/3 and 4/3 of v", [1 / 3, 1 / 3, 4 / 3])),
    ("seed-glued-pair-into-three", [1] * 5, [0.8, 0.8, 0, 0, 0],
     ("§4: (0.06, 0.12, 0.36, 1.0) m/s", [0.06, 0.06, 0.12, 0.36, 1.0])),
]


def balance(m, v0, v):
    e0 = sum(mi * x * x for mi, x in zip(m, v0))
    p0 = sum(mi * x for mi, x in zip(m, v0))
    e = sum(mi * x * x for mi, x in zip(m, v))
    p = sum(mi * x for mi, x in zip(m, v))
    return e / e0, p / p0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cradle", default="./target/release/cradle")
    a = ap.parse_args()
    print("| scene | model | final velocities (m/s) | KE after / before | momentum after / before |")
    print("|---|---|---|---|---|")
    for name, m, v0, (quote, qv) in SCENES:
        rows = []
        for model in ["hertz", "hard-sphere", "closure"]:
            out = subprocess.run(
                [a.cradle, "run", name, "--model", model, "--format", "csv"],
                check=True, capture_output=True, text=True).stdout
            r = next(csv.DictReader(io.StringIO(out)))
            v = [float(r[f"v_{i}"]) for i in range(len(m))]
            rows.append((model, v))
        rows.append((f"seed quote {quote}", qv))
        for model, v in rows:
            e, p = balance(m, v0, v)
            vs = ", ".join(f"{x:.4f}" for x in v)
            print(f"| {name} | {model} | ({vs}) | {e:.4f} | {p:.4f} |")


if __name__ == "__main__":
    main()
