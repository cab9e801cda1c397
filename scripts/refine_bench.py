#!/usr/bin/env python3
"""Adaptive refinement against the full grid and python-adaptive (issue #20).

    .venv/bin/python scripts/refine_bench.py [--cradle target/release/cradle] [--n 1000]
                                             [--out results/refine.md] [--no-learner]

For three 1000 x 1000 maps of the 5-ball cradle (the `ejected` column):
  A. mass of ball 2 x gap, one ball launched (examples/mass_gap.toml's ranges);
  B. the same with two balls launched;
  C. mass of ball 1 x mass of ball 3, touching balls;
runs the full sweep and the refined one (`[refine] column = "ejected"`),
fills the refined table (`cradle fill`: nearest computed scene) and counts
the cells whose `ejected` differs from the full grid's, with wall times.
Then python-adaptive's Learner2D (pip install adaptive), fed the full-grid
map as its function (in grid-index coordinates, points snapped to the grid),
until its points, filled the same way, reach 99.9% of the cells (checked
every 2,000 points, up to 5% of the scenes).
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from machine import cpu_model, git_rev  # noqa: E402
ROOT = os.path.dirname(HERE)
M = 0.06422266231947886

MAPS = {
    "A: mass[2] x gap, 1 launched": ("[1.0, 0.0, 0.0, 0.0, 0.0]", "mass[2]", f"logspace = [{M / 10!r}, {M * 10!r}, N]",
                                     "gap", "linspace = [0.0, 2e-5, N]"),
    "B: mass[2] x gap, 2 launched": ("[1.0, 1.0, 0.0, 0.0, 0.0]", "mass[2]", f"logspace = [{M / 10!r}, {M * 10!r}, N]",
                                     "gap", "linspace = [0.0, 2e-5, N]"),
    "C: mass[1] x mass[3], touching": ("[1.0, 0.0, 0.0, 0.0, 0.0]", "mass[1]", f"logspace = [{M / 10!r}, {M * 10!r}, N]",
                                       "mass[3]", f"logspace = [{M / 10!r}, {M * 10!r}, N]"),
}


def spec(velocity, p1, r1, p2, r2, n, refine):
    text = f"""[scene]
balls = 5
radius = 0.0125
density = 7850.0
velocity = {velocity}

[[axis]]
param = "{p1}"
{r1.replace("N]", f"{n}]")}

[[axis]]
param = "{p2}"
{r2.replace("N]", f"{n}]")}
"""
    if refine:
        text += '\n[refine]\ncolumn = "ejected"\n'
    return text




def column(path, name):
    import pandas as pd
    return pd.read_csv(path, usecols=[name])[name].to_numpy()


def learner_points_needed(full, n, step=2000, cap=0.05):
    """Learner2D on the full map; points needed for 99.9% of cells (or None)."""
    import adaptive
    import numpy as np
    from scipy import ndimage

    grid = full.reshape(n, n)

    def f(xy):
        i, j = int(round(xy[0])), int(round(xy[1]))
        return float(grid[i, j])

    learner = adaptive.Learner2D(f, bounds=[(0, n - 1), (0, n - 1)])
    goal = int(cap * n * n)
    while learner.npoints < goal:
        pts, _ = learner.ask(step)
        for p in pts:
            learner.tell(p, f(p))
        mask = np.ones((n, n), bool)
        for (x, y) in learner.data:
            mask[int(round(x)), int(round(y))] = False
        idx = ndimage.distance_transform_edt(mask, return_distances=False, return_indices=True)
        filled = grid[idx[0], idx[1]]
        acc = (filled == grid).mean()
        if acc >= 0.999:
            return learner.npoints, acc
    return None, None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cradle", default=os.path.join(ROOT, "target", "release", "cradle"))
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--out")
    ap.add_argument("--no-learner", action="store_true")
    a = ap.parse_args()
    cradle, n = os.path.abspath(a.cradle), a.n
    tmp = tempfile.mkdtemp(prefix="cradle-refine-")
    rows = []
    for name, m in MAPS.items():
        res = {}
        for kind in ("full", "refined"):
            p = os.path.join(tmp, f"{kind}.toml")
            open(p, "w").write(spec(*m, n, kind == "refined"))
            out = os.path.join(tmp, f"{kind}.csv")
            t = time.perf_counter()
            subprocess.run([cradle, "sweep", p, "--out", out, "--backend", "cpu"], check=True,
                           stderr=subprocess.DEVNULL)
            res[kind] = time.perf_counter() - t
        filled = os.path.join(tmp, "filled.csv")
        subprocess.run([cradle, "fill", os.path.join(tmp, "refined.csv"), "--out", filled], check=True,
                       stderr=subprocess.DEVNULL)
        full = column(os.path.join(tmp, "full.csv"), "ejected")
        got = column(filled, "ejected")
        computed = len(column(os.path.join(tmp, "refined.csv"), "ejected"))
        wrong = int((full != got).sum())
        lp = (None, None) if a.no_learner else learner_points_needed(full, n)
        rows.append((name, computed, wrong, res["full"], res["refined"], lp[0]))
        print(rows[-1], flush=True)
        for f in os.listdir(tmp):
            os.remove(os.path.join(tmp, f))
    rev = git_rev()
    total = n * n
    lines = [
        f"Machine: {cpu_model()}, {os.cpu_count()} cores; cradle at {rev}; CPU backend, default solver.",
        f"Command: `{' '.join(['python3', 'scripts/refine_bench.py'] + sys.argv[1:])}`.",
        "",
        f"| map ({n} x {n}, `ejected`) | scenes computed | cells wrong (filled vs full) | full sweep (s) | refined (s) | Learner2D points for 99.9% |",
        "|---|---|---|---|---|---|",
    ]
    for name, computed, wrong, tf, tr, lp in rows:
        lps = "not run" if a.no_learner else (f"{lp} ({lp / total:.2%})" if lp else "> 5%")
        lines.append(f"| {name} | {computed} ({computed / total:.2%}) | {wrong} ({1 - wrong / total:.3%} right) "
                     f"| {tf:.2f} | {tr:.2f} | {lps} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if a.out:
        with open(a.out, "w") as f:
            f.write("# Adaptive refinement against the full grid (issue #20)\n\n" + text)


if __name__ == "__main__":
    main()
