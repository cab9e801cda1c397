#!/usr/bin/env python3
"""Side-by-side benchmark on the grid100 workload (10,000 five-ball cradles):
hertz-cradle (CPU backend) against the numba peer, each timed in this one run,
each with its maximum error over the grid against one reference.

Reference: Richardson extrapolation of two tight cradle runs (tolerances
1.6e-8 and 4e-9, steps in ratio 2; Verlet is order 2 on this grid, as measured).
GPU rows run the WGSL shader on whatever adapter `--backend gpu` finds (here:
Mesa lavapipe, a CPU; set XDG_RUNTIME_DIR=/tmp WGPU_BACKEND=vulkan).

  python3 -m venv /tmp/peer && /tmp/peer/bin/pip install numpy numba
  cargo build --release
  /tmp/peer/bin/python scripts/bench_grid100.py --out results/bench_grid100.csv
"""
import argparse, csv, os, re, subprocess, sys, time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
CRADLE = os.path.join(ROOT, "target", "release", "cradle")
GRID = os.path.join(ROOT, "examples", "grid100.toml")
PEER = os.path.join(ROOT, "..", "shared", "peers", "numba_grid100.py")


def read(path):
    with open(path) as fh:
        r = csv.DictReader(fh)
        return [[float(row[f"v_{i}"]) for i in range(5)] for row in r]


def cradle(tmp, tol, extra=()):
    out = os.path.join(tmp, f"cradle_{tol:g}{''.join(extra)}.csv")
    t0 = time.perf_counter()
    backend = [] if "--backend" in extra else ["--backend", "cpu"]
    subprocess.run([CRADLE, "sweep", GRID, "--out", out, *backend, "--tolerance", str(tol), *extra],
                   check=True, stderr=subprocess.DEVNULL)
    return read(out), time.perf_counter() - t0


def max_err(a, ref):
    return max(abs(x - y) for ra, rr in zip(a, ref) for x, y in zip(ra, rr))


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--out", required=True)
    p.add_argument("--tmp", default="/tmp/bench_grid100")
    p.add_argument("--peer-div", type=float, nargs="*", default=[3000.0, 10000.0])
    p.add_argument("--no-gpu", action="store_true")
    a = p.parse_args()
    os.makedirs(a.tmp, exist_ok=True)
    r1, _ = cradle(a.tmp, 1.6e-8)
    r2, _ = cradle(a.tmp, 4e-9)
    ref = [[b + (b - x) / 3.0 for x, b in zip(ra, rb)] for ra, rb in zip(r1, r2)]
    rows = [("reference-spread", "", max_err(r2, ref), "")]
    for div in a.peer_div:
        out = os.path.join(a.tmp, f"numba_{div:g}.csv")
        t0 = time.perf_counter()
        res = subprocess.run([sys.executable, PEER, "--dt-div", str(div), "--out", out], check=True, capture_output=True, text=True)
        wall = float(re.search(r": ([0-9.]+) s,", res.stdout).group(1))  # the peer's own timing, compile excluded
        rows.append((f"numba-verlet dt=t_c/{div:g}", "", max_err(read(out), ref), wall))
    for tol in [1e-4, 1e-5, 1e-6, 1e-7]:
        v, wall = cradle(a.tmp, tol)
        rows.append((f"cradle cpu f64 verlet", tol, max_err(v, ref), wall))
    v, wall = cradle(a.tmp, 1e-5, ["--precision", "f32"])
    rows.append(("cradle cpu f32 verlet", 1e-5, max_err(v, ref), wall))
    if not a.no_gpu:
        for prec, tol in [("f32", 1e-5), ("f64", 1e-6)]:
            v, wall = cradle(a.tmp, tol, ["--backend", "gpu", "--precision", prec])
            rows.append((f"cradle gpu(lavapipe) {prec} verlet", tol, max_err(v, ref), wall))
    with open(a.out, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["run", "tolerance", "max_error_over_v_in", "wall_s"])
        for r in rows:
            w.writerow(r)
            print(*r, sep="\t")


if __name__ == "__main__":
    main()
