#!/usr/bin/env python3
"""Throughput of `cradle sweep` on every backend (issue #17), as one table.

    python3 scripts/throughput.py [--cradle target/release/cradle] [--out results/throughput.md]
                                  [--reps 2] [--gpu auto|yes|no] [--skip-stress]
                                  [--gpu-profile hardware|software|TEXT ...] [--gpu-reps N]

Runs, each timed wall-clock from process start to the CSV written (best of
--reps), the 10^6-scene mass x gap grid of the 5-ball cradle (`grid1000`, made
by scripts/grid.py) and examples/stress.toml (3,360 mixed chains up to 64
balls):
  - the CPU backend on all cores and on one thread (the scaling);
  - `--model hard-sphere` (no integration at all: the floor set by scene
    building, formatting and writing), on all cores and on one thread;
  - the GPU backend in f64 and f32, when wgpu finds an adapter (`--gpu auto`:
    a hardware GPU only, `yes`: lavapipe too, `no`: never), once per
    `--gpu-profile` (CRADLE_GPU_PROFILE: `hardware`, `software`, or with
    `,key=value` changes; none given: the adapter's own profile).
Prints scenes/s, the stage thread-seconds the sidecar records, what the GPU
did (dispatches, rounds, share of the wall time with work in flight, scenes
sent to the CPU engine), and the largest velocity difference of each GPU
table against the CPU's. Names the
machine (CPU model, cores) and the GPU adapter. Python 3 standard library only.
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from machine import cpu_model, git_rev  # noqa: E402
ROOT = os.path.dirname(HERE)



def sweep(cradle, spec, out, args, reps, env=None):
    """Best wall time of `reps` runs; the sidecar of the last one."""
    best = None
    for _ in range(reps):
        t = time.perf_counter()
        r = subprocess.run([cradle, "sweep", spec, "--out", out] + args, env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        w = time.perf_counter() - t
        if r.returncode != 0:
            return None, r.stderr.strip().splitlines()[-1:]
        best = w if best is None else min(best, w)
    return best, json.load(open(out + ".json"))


def max_dv(a, b):
    """Largest |v_a − v_b| over scenes and balls (both ok), relative to v_in = 1."""
    def rows(p):
        with open(p) as f:
            r = csv.DictReader(f)
            cols = [c for c in r.fieldnames if c.startswith("v_")]
            for row in r:
                yield row["id"], row["status"], [row[c] for c in cols]
    worst = 0.0
    for (ia, sa, va), (ib, sb, vb) in zip(rows(a), rows(b)):
        assert ia == ib
        if sa == sb == "ok":
            for x, y in zip(va, vb):
                if x and y:
                    worst = max(worst, abs(float(x) - float(y)))
    return worst


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cradle", default=os.path.join(ROOT, "target", "release", "cradle"))
    ap.add_argument("--out", help="also write the table (markdown) here")
    ap.add_argument("--reps", type=int, default=2)
    ap.add_argument("--gpu", choices=["auto", "yes", "no"], default="auto")
    ap.add_argument("--skip-stress", action="store_true")
    ap.add_argument("--gpu-profile", action="append", default=[],
                    help="CRADLE_GPU_PROFILE for the GPU rows (repeatable: one pair of rows each)")
    ap.add_argument("--gpu-reps", type=int, help="runs per GPU row on grid1000 (default: --reps)")
    a = ap.parse_args()
    cradle = os.path.abspath(a.cradle)
    tmp = tempfile.mkdtemp(prefix="cradle-throughput-")
    grid = os.path.join(tmp, "grid1000.toml")
    with open(grid, "w") as f:
        subprocess.run([sys.executable, os.path.join(HERE, "grid.py"), "1000", "1000"], stdout=f, check=True)
    stress = os.path.join(ROOT, "examples", "stress.toml")
    cores = os.cpu_count()
    rev = git_rev()

    gpu_args = []
    if a.gpu != "no":
        probe = os.path.join(tmp, "probe.csv")
        one = os.path.join(tmp, "one.toml")
        open(one, "w").write("[scene]\nballs = 2\nvelocity = [1.0, 0]\n")
        r = subprocess.run([cradle, "sweep", one, "--out", probe, "--backend", "gpu" if a.gpu == "yes" else "auto",
                            "--precision", "f32"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if r.returncode == 0 and json.load(open(probe + ".json"))["backend"] == "gpu":
            adapter = json.load(open(probe + ".json"))["adapter"]
            for prof in a.gpu_profile or [None]:
                env = None if prof is None else dict(os.environ, CRADLE_GPU_PROFILE=prof)
                tag = "" if prof is None else f" ({prof})"
                gpu_args += [(f"gpu f64{tag}", ["--backend", "gpu", "--precision", "f64"], env),
                             (f"gpu f32{tag}", ["--backend", "gpu", "--precision", "f32"], env)]
        else:
            adapter = "none found" if a.gpu == "auto" else "none: " + r.stderr.strip()[-200:]
    else:
        adapter = "not asked (--gpu no)"

    runs = [("cpu, all cores", ["--backend", "cpu"], None),
            ("cpu, 1 thread", ["--backend", "cpu", "--threads", "1"], None),
            ("hard-sphere floor, all cores", ["--backend", "cpu", "--model", "hard-sphere"], None),
            ("hard-sphere floor, 1 thread", ["--backend", "cpu", "--model", "hard-sphere", "--threads", "1"], None)]
    runs += gpu_args
    lines = [
        f"# Throughput of `cradle sweep` (commit {rev})",
        "",
        f"Machine: {cpu_model()}, {cores} cores; GPU adapter: {adapter}.",
        f"Command: `python3 scripts/throughput.py {' '.join(sys.argv[1:])}` (best of {a.reps} runs,"
        " wall clock from process start to the CSV written).",
        "",
        "| workload | run | scenes | wall (s) | scenes/s | jobs | integration | formatting | writing | busy | gpu | max dv vs cpu |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    print("\n".join(lines), flush=True)
    workloads = [("grid1000", grid, a.reps)]
    if not a.skip_stress:
        workloads.append(("stress.toml", stress, 1))
    for name, spec, reps in workloads:
        base = None
        for label, args, env in runs:
            if name == "stress.toml" and "1 thread" in label:
                continue
            safe = "".join(ch if ch.isalnum() else "_" for ch in label)
            out = os.path.join(tmp, f"{name}-{safe}.csv")
            r = a.gpu_reps if label.startswith("gpu") and a.gpu_reps and reps > 1 else reps
            wall, side = sweep(cradle, spec, out, args, r, env)
            if wall is None:
                line = f"| {name} | {label} | | FAILED: {side} | | | | | | | | |"
            else:
                st = side.get("stages_s", {})
                n = side["scenes_ok"] + side["scenes_not_ok"]
                dv = ""
                if label == "cpu, all cores":
                    base = out
                elif label.startswith("gpu") and base:
                    dv = f"{max_dv(out, base):.1e}"
                g = st.get("gpu")
                gpu = (f"{g['dispatches']:,} / {g['rounds']:,} / {g['in_flight_fraction']:.2f} / "
                       f"{g.get('scenes_on_cpu', 0):,}") if g else ""
                line = (f"| {name} | {label} | {n} | {wall:.2f} | {n / wall:,.0f} | {st.get('jobs', 0):.2f} | "
                        f"{st.get('integration', 0):.2f} | {st.get('formatting', 0):.2f} | {st.get('writing', 0):.2f} | "
                        f"{st.get('busy_fraction', 0):.2f} | {gpu} | {dv} |")
            lines.append(line)
            print(line, flush=True)
            for p in (out, out + ".json"):
                if label not in ("cpu, all cores",) and os.path.exists(p):
                    os.remove(p)
    lines += ["", "Stage columns: thread-seconds summed over the pipeline's lanes (sidecar `stages_s`);"
              " busy: the lanes' share of wall time spent working; gpu: dispatches / rounds / share of the"
              " wall time with a submission in flight / scenes run on the CPU engine instead (`stages_s.gpu`)."]
    if a.out:
        open(a.out, "w").write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
