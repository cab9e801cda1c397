#!/usr/bin/env python3
"""Steps per swing of pendulum runs, per method and tolerance (issue: free
flight under gravity must cost few steps). Two scenes, 10 swings each, L = 0.2 m:

- free: two balls lifted 1 cm together (they never touch): only free flight;
- cradle: a 5-ball cradle with one ball lifted 1 cm: ~20 contacts a swing.

For the cradle, the error of the final velocities against a yoshida6 run at
tolerance 1e-10 (relative to v_in = sqrt(2 g h)), the energy error and the
wall time are given too. Writes CSV to --out and a markdown table to stdout.

    python3 scripts/pendulum_steps.py --out results/pendulum_steps.csv
"""
import argparse
import csv
import io
import math
import os
import subprocess
import tempfile
import time

G, L, H, SWINGS = 9.80665, 0.2, 0.01, 10
T = 2 * math.pi * math.sqrt(L / G)
SCENES = {
    "free": f"balls = 2\ngap = 0.01\n[launch]\nballs = 2\nheight = {H}\n",
    "cradle": f"balls = 5\n[launch]\nballs = 1\nheight = {H}\n",
}
TAIL = f"[pendulum]\nlength = {L}\n[stop]\nduration = {SWINGS * T}\n"


def run(cradle, path, method, tol):
    t0 = time.perf_counter()
    out = subprocess.run([cradle, "run", path, "--method", method, "--tolerance", str(tol),
                          "--format", "csv"], check=True, capture_output=True, text=True).stdout
    return next(csv.DictReader(io.StringIO(out))), time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cradle", default="./target/release/cradle")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    d = tempfile.mkdtemp()
    paths = {}
    for k, text in SCENES.items():
        paths[k] = os.path.join(d, k + ".toml")
        with open(paths[k], "w") as f:
            f.write(text + TAIL)
    ref, _ = run(a.cradle, paths["cradle"], "yoshida6", 1e-10)
    v_in = math.sqrt(2 * G * H)
    rows = []
    for method in ["verlet", "suzuki4", "yoshida4", "yoshida6", "kahanli6"]:
        for tol in [1e-4, 1e-6, 1e-8]:
            free, _ = run(a.cradle, paths["free"], method, tol)
            cr, wall = run(a.cradle, paths["cradle"], method, tol)
            err = max(abs(float(cr[f"v_{i}"]) - float(ref[f"v_{i}"])) for i in range(5)) / v_in
            rows.append({
                "method": method, "tolerance": tol, "cradle_status": cr["status"],
                "free_steps_per_swing": int(free["steps"]) / SWINGS,
                "cradle_steps_per_swing": int(cr["steps"]) / SWINGS,
                "cradle_contacts_per_swing": int(cr["contacts"]) / SWINGS,
                "cradle_error": err, "cradle_energy_error": float(cr["energy_error"]),
                "cradle_wall_s": round(wall, 3),
            })
    with open(a.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("| method | tolerance | free flight: steps/swing | cradle: steps/swing | contacts/swing "
          "| cradle status | cradle error (v/v_in) | energy error | wall (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['method']} | {r['tolerance']:.0e} | {r['free_steps_per_swing']:.1f} "
              f"| {r['cradle_steps_per_swing']:.0f} | {r['cradle_contacts_per_swing']:.1f} | {r['cradle_status']} "
              f"| {r['cradle_error']:.1e} | {r['cradle_energy_error']:.1e} | {r['cradle_wall_s']} |")


if __name__ == "__main__":
    main()
