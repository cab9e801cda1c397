#!/usr/bin/env python3
"""Work-precision benchmark on the grid100 workload (10,000 five-ball cradles):
every method of hertz-cradle over a range of tolerances, f64 and f32, CPU and
GPU backends, side by side with the numba peer in the same run. Each row: the
maximum and median error over the grid against one reference, and wall time.

Reference: suzuki4 at tolerance 1e-11, checked against yoshida6 at 1e-11 and
against a Richardson-extrapolated pair of Verlet runs (the spreads are
printed and written as rows `reference-check-*`).

  python3 -m venv .venv && .venv/bin/pip install -r scripts/requirements.txt
  cargo build --release
  XDG_RUNTIME_DIR=/tmp WGPU_BACKEND=vulkan \\
    .venv/bin/python scripts/work_precision.py --out results/work_precision.csv \\
    --plot results/work_precision.png --speedup results/work_precision_speedup.csv

The peer is vendored in scripts/peers/numba_grid100.py (versions pinned in
scripts/requirements.txt).
"""
import argparse, csv, math, os, re, statistics, subprocess, sys, time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CRADLE = os.path.join(ROOT, "target", "release", "cradle")
GRID = os.path.join(ROOT, "examples", "grid100.toml")
PEER = os.path.join(ROOT, "scripts", "peers", "numba_grid100.py")


def read(path):
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    return [[float(r[f"v_{i}"]) for i in range(5)] for r in rows], sum(int(r.get("steps", 0) or 0) for r in rows)


def cradle(tmp, method, tol, precision="f64", backend="cpu", repeat=1):
    """Run the sweep `repeat` times (the same outputs each time); median wall."""
    out = os.path.join(tmp, f"{method}_{tol:g}_{precision}_{backend}.csv")
    walls = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run([CRADLE, "sweep", GRID, "--out", out, "--backend", backend, "--method", method,
                        "--tolerance", str(tol), "--precision", precision], check=True, stderr=subprocess.DEVNULL)
        walls.append(time.perf_counter() - t0)
    v, steps = read(out)
    return v, statistics.median(walls), steps


def errors(v, ref):
    return [max(abs(x - y) for x, y in zip(a, b)) for a, b in zip(v, ref)]


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--out", required=True)
    p.add_argument("--plot")
    p.add_argument("--speedup", help="CSV: every method's wall time and speedup at each peer row's error")
    p.add_argument("--tmp", default="/tmp/work_precision")
    p.add_argument("--no-gpu", action="store_true")
    a = p.parse_args()
    os.makedirs(a.tmp, exist_ok=True)
    rows = []

    def add(name, method, backend, precision, tol, v, wall, steps):
        e = errors(v, ref)
        row = dict(run=name, method=method, backend=backend, precision=precision, tolerance=tol,
                   max_error=max(e), median_error=statistics.median(e), wall_s=round(wall, 3), steps=steps)
        rows.append(row)
        print(*row.values(), sep="\t", flush=True)

    ref, _, _ = cradle(a.tmp, "suzuki4", 1e-11)
    check6, _, _ = cradle(a.tmp, "yoshida6", 1e-11)
    va, _, _ = cradle(a.tmp, "verlet", 1.6e-8)
    vb, _, _ = cradle(a.tmp, "verlet", 4e-9)
    rich = [[y + (y - x) / 3.0 for x, y in zip(p1, p2)] for p1, p2 in zip(va, vb)]
    add("reference-check-yoshida6", "yoshida6", "cpu", "f64", 1e-11, check6, 0, 0)
    add("reference-check-verlet-richardson", "verlet", "cpu", "f64", "", rich, 0, 0)

    for div in [1000.0, 3000.0, 10000.0, 30000.0, 100000.0]:
        out = os.path.join(a.tmp, f"numba_{div:g}.csv")
        res = subprocess.run([sys.executable, PEER, "--dt-div", str(div), "--out", out], check=True, capture_output=True, text=True)
        wall = float(re.search(r": ([0-9.]+) s,", res.stdout).group(1))  # the peer's own timing, JIT excluded
        steps = int(re.search(r"([0-9,]+) chain steps", res.stdout).group(1).replace(",", ""))
        add(f"numba dt=t_c/{div:g}", "numba-verlet", "numba", "f64", "", read(out)[0], wall, steps)

    decades = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
    # kahanli6 meets 1e-4 already at the 20-steps-per-contact floor: 1e-3
    # (where the settle floor ends slow tails early) brackets the coarse end.
    plan = {"verlet": [1e-4, 1e-5, 1e-6, 1e-7], "suzuki4": decades,
            "yoshida4": [1e-4, 1e-6, 1e-8], "yoshida6": decades,
            "kahanli6": [1e-3] + decades}
    for method, tols in plan.items():
        for tol in tols:
            # CPU rows: median of 3 runs (short runs on 2 cores are noisy)
            add("cradle", method, "cpu", "f64", tol, *cradle(a.tmp, method, tol, repeat=3))
    for method in ["verlet", "suzuki4"]:
        add("cradle", method, "cpu", "f32", 1e-5, *cradle(a.tmp, method, 1e-5, "f32"))
    if not a.no_gpu:
        for method, tol, prec in [("suzuki4", 1e-6, "f64"), ("suzuki4", 1e-5, "f32"), ("verlet", 1e-6, "f64")]:
            add("cradle", method, "gpu", prec, tol, *cradle(a.tmp, method, tol, prec, "gpu"))

    with open(a.out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)

    # At equal error: each cradle method's wall time at each peer row's max
    # error, interpolated log-log between the method's two bracketing rows
    # (CPU, f64), and the measured order (slope of log error over log steps).
    speed = []
    peers = [r for r in rows if r["backend"] == "numba"]
    for method in plan:
        pts = sorted((r["max_error"], r["wall_s"], r["steps"]) for r in rows
                     if r["run"] == "cradle" and r["method"] == method and r["backend"] == "cpu"
                     and r["precision"] == "f64")
        lx = [math.log(p[2]) for p in pts]
        ly = [math.log(p[0]) for p in pts]
        mx, my = statistics.mean(lx), statistics.mean(ly)
        order = -sum((x - mx) * (y - my) for x, y in zip(lx, ly)) / sum((x - mx) ** 2 for x in lx)
        for pr in peers:
            e = pr["max_error"]
            wall = None
            for (e1, w1, _), (e0, w0, _) in zip(pts, pts[1:]):
                if e1 <= e <= e0:  # e1 < e0: the finer row first
                    f = (math.log(e) - math.log(e0)) / (math.log(e1) - math.log(e0))
                    wall = math.exp(math.log(w0) + f * (math.log(w1) - math.log(w0)))
            speed.append(dict(method=method, measured_order=round(order, 2), peer=pr["run"],
                              peer_max_error=e, peer_wall_s=pr["wall_s"],
                              cradle_wall_s=round(wall, 3) if wall else "",
                              speedup=round(pr["wall_s"] / wall, 1) if wall else ""))
            print(*speed[-1].values(), sep="\t", flush=True)
    if a.speedup:
        with open(a.speedup, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(speed[0].keys()))
            w.writeheader()
            w.writerows(speed)

    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(7, 5))
        series = {}
        for r in rows:
            if r["run"].startswith("reference"):
                continue
            key = f'{r["method"]} ({r["backend"]}, {r["precision"]})'
            series.setdefault(key, []).append((r["max_error"], r["wall_s"]))
        for key, pts in series.items():
            pts.sort()
            ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-" if len(pts) > 1 else "s", label=key)
        ax.set_xlabel("max error over the grid  |v − v_ref| / v_in")
        ax.set_ylabel("wall time for 10,000 scenes (s), 2 cores")
        ax.set_title("Work-precision on grid100 (5-ball cradles, mass × gap)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(a.plot, dpi=120)


if __name__ == "__main__":
    main()
