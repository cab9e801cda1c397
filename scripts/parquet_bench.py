#!/usr/bin/env python3
"""Parquet against CSV, and the Python module against the CLI (issue #21).

    .venv/bin/python scripts/parquet_bench.py [--cradle target/release/cradle]
                                              [--reps 3] [--out results/parquet.md]

Needs pyarrow and pandas, and the module (`pip install ./python`) for the
last table. Measures, on the 10^6-scene mass x gap grid of the 5-ball cradle
(`grid1000`, scripts/grid.py; examples/mass_gap.toml's ranges at 1000 x 1000):
  - `cradle sweep` writing CSV and writing Parquet (wall, best of --reps,
    the two formats alternating), and the files' sizes;
  - reading each whole into pandas (`read_csv` / `read_parquet`), and the
    three columns a phase map needs (`usecols` / `columns`), best of --reps;
  - that the two tables hold the same values (every column, bit for bit);
and on grid100 (examples/grid100.toml's sweep, via grid.py 100 100)
`hertz_cradle.sweep` in this process against the `cradle sweep` process
(first call apart: it pays for the imports and the GPU probe).
"""
import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from machine import cpu_model, git_rev  # noqa: E402
ROOT = os.path.dirname(HERE)




def best(f, reps):
    t = []
    for _ in range(reps):
        s = time.perf_counter()
        f()
        t.append(time.perf_counter() - s)
    return min(t)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cradle", default=os.path.join(ROOT, "target", "release", "cradle"))
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--out")
    a = ap.parse_args()
    import numpy as np
    import pandas as pd

    cradle = os.path.abspath(a.cradle)
    tmp = tempfile.mkdtemp(prefix="cradle-parquet-")
    grid = os.path.join(tmp, "grid1000.toml")
    with open(grid, "w") as f:
        subprocess.run([sys.executable, os.path.join(HERE, "grid.py"), "1000", "1000"], stdout=f, check=True)
    csv_path, pq_path = os.path.join(tmp, "g.csv"), os.path.join(tmp, "g.parquet")

    def sweep(out, spec=grid):
        subprocess.run([cradle, "sweep", spec, "--out", out, "--backend", "cpu"],
                       check=True, stderr=subprocess.DEVNULL)

    write = {"csv": [], "parquet": []}
    for _ in range(a.reps):
        for fmt, p in (("csv", csv_path), ("parquet", pq_path)):
            s = time.perf_counter()
            sweep(p)
            write[fmt].append(time.perf_counter() - s)
    size = {f: os.path.getsize(p) for f, p in (("csv", csv_path), ("parquet", pq_path))}

    three = ["mass[2]", "gap", "ejected"]
    r_csv = best(lambda: pd.read_csv(csv_path), a.reps)
    r_pq = best(lambda: pd.read_parquet(pq_path), a.reps)
    r_csv3 = best(lambda: pd.read_csv(csv_path, usecols=three), a.reps)
    r_pq3 = best(lambda: pd.read_parquet(pq_path, columns=three), a.reps)

    c, p = pd.read_csv(csv_path), pd.read_parquet(pq_path)
    same = list(c.columns) == list(p.columns) and all(
        (c[k] == p[k].astype(str)).all() if k == "status"
        else np.array_equal(c[k].to_numpy("float64"), p[k].to_numpy("float64"), equal_nan=True)
        for k in c.columns)

    g100 = os.path.join(tmp, "grid100.toml")
    with open(g100, "w") as f:
        subprocess.run([sys.executable, os.path.join(HERE, "grid.py"), "100", "100"], stdout=f, check=True)
    cli100 = best(lambda: sweep(os.path.join(tmp, "g100.parquet"), g100), 2 * a.reps + 1)
    try:
        import hertz_cradle as hc
        s = time.perf_counter()
        hc.sweep(g100, backend="cpu", progress=False)
        first = time.perf_counter() - s
        py100 = best(lambda: hc.sweep(g100, backend="cpu", progress=False), 2 * a.reps + 1)
    except ImportError:
        first = py100 = None

    rev = git_rev()
    import pyarrow
    lines = [
        f"Machine: {cpu_model()}, {os.cpu_count()} cores; cradle at {rev}; CPU backend; "
        f"pandas {pd.__version__}, pyarrow {pyarrow.__version__}, Python {platform.python_version()}.",
        f"Command: `{' '.join(['python3', 'scripts/parquet_bench.py'] + sys.argv[1:])}` (best of {a.reps}).",
        "",
        "| grid1000 (10^6 scenes) | CSV | Parquet | Parquet / CSV |",
        "|---|---|---|---|",
        f"| `cradle sweep` wall (s) | {min(write['csv']):.2f} | {min(write['parquet']):.2f} | "
        f"{min(write['parquet']) / min(write['csv']):.2f} |",
        f"| file size (MB) | {size['csv'] / 1e6:.1f} | {size['parquet'] / 1e6:.1f} | "
        f"{size['parquet'] / size['csv']:.1%} |",
        f"| pandas, whole table (s) | {r_csv:.3f} | {r_pq:.3f} | {r_csv / r_pq:.1f}x faster |",
        f"| pandas, `mass[2]`, `gap`, `ejected` (s) | {r_csv3:.3f} | {r_pq3:.3f} | {r_csv3 / r_pq3:.1f}x faster |",
        "",
        f"Same values in every column, bit for bit: {'yes' if same else 'NO'}.",
        "",
        "| grid100 (10^4 scenes), CPU | wall (s) |",
        "|---|---|",
        f"| `cradle sweep --out FILE.parquet` (process) | {cli100:.3f} |",
    ]
    if py100 is not None:
        lines += [
            f"| `hertz_cradle.sweep(spec)` → pyarrow.Table | {py100:.3f} ({py100 / cli100:.2f}x the CLI) |",
            f"| the same, first call of the process | {first:.3f} |",
        ]
    text = "\n".join(lines) + "\n"
    print(text)
    if a.out:
        with open(a.out, "w") as f:
            f.write("# Parquet output and the Python module (issue #21)\n\n" + text)


if __name__ == "__main__":
    main()
