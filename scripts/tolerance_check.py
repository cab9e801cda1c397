#!/usr/bin/env python3
"""Is every requested tolerance met? grid100 (10,000 five-ball cradles) at 8
tolerances per decade for every method (f64, CPU), each compared with the
reference of scripts/work_precision.py (suzuki4 at 1e-11): the maximum error
over all scenes and balls, |v − v_ref|/v_in, and its ratio to the tolerance.
Decade points alone hide misses: the worst scene's error is not monotone in
the step (event timings shift), so the error models are checked densely.

  cargo build --release
  python3 scripts/tolerance_check.py --out results/tolerance_check.csv

Verlet is checked down to 1e-7 and yoshida4 to 1e-9 (below that they take
minutes per point); suzuki4, yoshida6 and kahanli6 to 1e-10. Exits 1 if any ratio > 1.
"""
import argparse, csv, os, subprocess, sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CRADLE = os.path.join(ROOT, "target", "release", "cradle")
GRID = os.path.join(ROOT, "examples", "grid100.toml")
LOWEST = {"verlet": 1e-7, "yoshida4": 1e-9, "suzuki4": 1e-10, "yoshida6": 1e-10, "kahanli6": 1e-10}


def sweep(tmp, method, tol):
    out = os.path.join(tmp, f"tc_{method}_{tol:.3g}.csv")
    subprocess.run([CRADLE, "sweep", GRID, "--out", out, "--backend", "cpu", "--method", method,
                    "--tolerance", repr(tol)], check=True, stderr=subprocess.DEVNULL)
    with open(out) as fh:
        rows = list(csv.DictReader(fh))
    return [[float(r[f"v_{i}"]) for i in range(5)] for r in rows], sum(int(r["steps"]) for r in rows)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--out", required=True)
    p.add_argument("--tmp", default="/tmp/tolerance_check")
    p.add_argument("--per-decade", type=int, default=8)
    p.add_argument("--methods", help="comma-separated subset (default: every method)")
    a = p.parse_args()
    os.makedirs(a.tmp, exist_ok=True)
    ref, _ = sweep(a.tmp, "suzuki4", 1e-11)
    rows, worst = [], 0.0
    for method, lowest in LOWEST.items():
        if a.methods and method not in a.methods.split(","):
            continue
        k = 0
        while (tol := 10 ** (-3 - k / a.per_decade)) >= lowest * 0.999:
            v, steps = sweep(a.tmp, method, tol)
            err = max(max(abs(x - y) for x, y in zip(s, r)) for s, r in zip(v, ref))
            rows.append(dict(method=method, tolerance=f"{tol:.3g}", max_error=f"{err:.3g}",
                             ratio=f"{err / tol:.3f}", steps=steps))
            worst = max(worst, err / tol)
            print(*rows[-1].values(), sep="\t", flush=True)
            k += 1
    with open(a.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    print(f"worst error/tolerance: {worst:.3f}")
    sys.exit(0 if worst <= 1.0 else 1)


if __name__ == "__main__":
    main()
