#!/usr/bin/env python3
"""The engine against the numba Verlet peer (scripts/peers/numba_chain.py) on issue
#30's chain workload, side by side in one run, at equal error.

Workload: an uncompressed 1,000-bead steel chain (R = 5 mm) struck at bead 0 at
0.1 m/s, run 21 ms (the wave near bead 890), probes at beads 250 and 750.
Error = the largest of the probes' peak times / run time, their peak velocities /
striker speed, and every bead's final velocity / striker speed, against a tight
reference (this engine, yoshida4 at tolerance 1e-10).

1. One chain, one thread: `cradle run` at the default tolerance (1e-6) and at 1e-8
   (kahanli6, the default method, and yoshida4); its final velocities come from a
   trace of every bead at t = 0 and the end. The peer is run at two step counts
   (its order fitted), then at the step count that gives the engine's error at the
   default tolerance (run for real); at 1e-8 the peer's time at equal error is
   extrapolated from the fit (it would take 10^3 s and more), and says so.
2. A sweep of 64 chains on 2 threads: striker speeds 0.01 .. 1 m/s (log), each run
   for 21 ms x (0.1/v)^(1/5) (Hertz chains have no velocity scale: every chain is
   the reference chain rescaled, so one reference serves all 64). `cradle sweep
   --threads 2` against the peer's prange on 2 threads (NUMBA_NUM_THREADS=2) at the
   equal-error step count; the peer sweep runs 1/16 of those steps and its time is
   multiplied by 16 (a fixed-step code's time is linear in its steps), as printed.

  cargo build --release
  python3 -m venv /tmp/nb && /tmp/nb/bin/pip install numba numpy
  NUMBA_NUM_THREADS=2 /tmp/nb/bin/python scripts/chain_peer_bench.py > results/chain_peer.md
  (then the "Machine" and "Reading it" notes below the tables, by hand)
"""
import csv, math, os, subprocess, sys, tempfile, time
import numba
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "peers"))
import numba_chain as peer  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CRADLE = os.environ.get("CRADLE_BIN", os.path.join(ROOT, "target", "release", "cradle"))
N, V, T = 1000, 0.1, 0.021
PROBES = [250, 750]
TMP = tempfile.mkdtemp(prefix="chain_peer_")


def scene(path, record):
    with open(path, "w") as f:
        f.write(f"balls = {N}\nradius = 0.005\n[launch]\nballs = 1\nvelocity = {V}\n"
                f"[probes]\nbeads = {PROBES}\n[stop]\nduration = {T}\n")
        if record:
            f.write(f"[record]\nbeads = {list(range(N))}\nevery = {T}\n")
    return path


def engine_run(method, tol):
    """(wall s, peaks[p, (t, v)], final v[i], steps) of one `cradle run`."""
    sc = scene(os.path.join(TMP, "chain.toml"), True)
    trace = os.path.join(TMP, f"trace_{method}_{tol:g}.csv")
    args = [CRADLE, "run", sc, "--format", "csv", "--method", method, "--tolerance", str(tol)]
    # Timed without the trace (a trace is written by the reported run, run
    # once more with its rows: the same bits, not part of the run's cost).
    t0 = time.perf_counter()
    subprocess.run(args, check=True, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    out = subprocess.run(args + ["--trace", trace], check=True, capture_output=True, text=True).stdout
    row = next(csv.DictReader(out.splitlines()))
    assert row["status"] == "ok", row
    peaks = np.array([[float(row[f"arrival_{p}"]), float(row[f"peak_v_{p}"])] for p in PROBES])
    with open(trace) as f:
        last = list(csv.DictReader(f))[-1]
    assert abs(float(last["t"]) - T) < 1e-12 * T, last["t"]
    v = np.array([float(last[f"v_{i}"]) for i in range(N)])
    return wall, peaks, v, int(row["steps"]), float(row["error_estimate"] or "nan")


def error(peaks, v, ref, scale=1.0, t_end=T, v0=V):
    """The workload's error of one chain against the reference (rescaled by `scale`)."""
    rp, rv = ref
    e = np.max(np.abs(peaks[:, 0] - rp[:, 0] * scale)) / t_end
    e = max(e, np.max(np.abs(peaks[:, 1] - rp[:, 1] * v0 / V)) / v0)
    if v is not None:
        e = max(e, np.max(np.abs(v - rv * v0 / V)) / v0)
    return e


def main():
    threads = os.environ.get("NUMBA_NUM_THREADS", "all")
    print("# Granular chains against a numba Verlet peer (issue #30)\n")
    print(f"Made by `NUMBA_NUM_THREADS={threads} python scripts/chain_peer_bench.py` "
          f"({time.strftime('%Y-%m-%d')}), engine `{CRADLE}`, numba {numba.__version__}.\n")
    peer.compile_once()
    t0 = time.perf_counter()
    _, rp, rv, rsteps, _ = engine_run("yoshida4", 1e-10)
    print(f"Reference: yoshida4 at tolerance 1e-10, {rsteps:,} steps, {time.perf_counter() - t0:.1f} s.\n")
    ref = (rp, rv)

    print("## One chain, one thread (1,000 beads, 21 ms)\n")
    print("| code | setting | error | error_estimate | steps (reported run) | wall (s) | bead-steps/s (reported run) |")
    print("|---|---|---|---|---|---|---|")
    eng = {}
    for method, tol in [("kahanli6", 1e-6), ("kahanli6", 1e-8), ("yoshida4", 1e-8)]:
        wall, p, v, steps, est = engine_run(method, tol)
        e = error(p, v, ref)
        eng[(method, tol)] = (e, wall)
        print(f"| cradle run | {method}, tol {tol:g} | {e:.2e} | {est:.2e} | {steps:,} | {wall:.3f} | {N * steps / wall:.3e} |")
    fit = []
    for steps in [1_000_000, 2_000_000]:
        wall, p, v = peer.run(N, [V], [T], steps, PROBES)
        e = error(p[0], v[0], ref)
        fit.append((steps, e, wall))
        print(f"| numba Verlet | {steps:,} steps | {e:.2e} | | {steps:,} | {wall:.3f} | {N * steps / wall:.3e} |")
    (s1, e1, w1), (s2, e2, w2) = fit
    order = math.log(e1 / e2) / math.log(s2 / s1)
    per_step = w2 / s2

    def steps_for(e):
        return int(math.ceil(s2 * (e2 / e) ** (1.0 / order)))

    e_def, w_def = eng[("kahanli6", 1e-6)]
    s_eq = steps_for(e_def)
    wall, p, v = peer.run(N, [V], [T], s_eq, PROBES)
    e_peer = error(p[0], v[0], ref)
    # The sweep's rows hold the probes' final velocities only (1,000 beads):
    # the same metric on the peer's side.
    e_peer_probes = max(error(p[0], None, ref), float(np.max(np.abs(v[0][PROBES] - rv[PROBES]))) / V)
    print(f"| numba Verlet | {s_eq:,} steps (equal error, run) | {e_peer:.2e} | | {s_eq:,} | {wall:.3f} | {N * s_eq / wall:.3e} |")
    print(f"\nThe peer's error falls as steps^-{order:.2f} (fitted on the two runs above).\n")
    print("| engine setting | engine error | engine (s) | peer steps at that error | peer (s) | speed-up |")
    print("|---|---|---|---|---|---|")
    print(f"| kahanli6, tol 1e-6 (default) | {e_def:.2e} | {w_def:.3f} | {s_eq:,} | {wall:.1f} (run, error {e_peer:.2e}) | {wall / w_def:.0f}x |")
    for key in [("kahanli6", 1e-8), ("yoshida4", 1e-8)]:
        e, w = eng[key]
        s = steps_for(e)
        print(f"| {key[0]}, tol {key[1]:g} | {e:.2e} | {w:.3f} | {s:,} | {s * per_step:.0f} (extrapolated) | {s * per_step / w:.0f}x |")

    print("\n## A sweep of 64 chains on 2 threads (striker 0.01 .. 1 m/s, each run 21 ms x (0.1/v)^(1/5))\n")
    vs = np.logspace(-2, 0, 64)
    scales = (V / vs) ** 0.2
    ts = T * scales
    pts = os.path.join(TMP, "points.csv")
    with open(pts, "w") as f:
        f.write("launch.velocity,duration\n")
        for v0, t in zip(vs, ts):
            f.write(f"{float(v0)!r},{float(t)!r}\n")
    scene(os.path.join(TMP, "base.toml"), False)
    sw = os.path.join(TMP, "sweep.toml")
    with open(sw, "w") as f:
        f.write('scene = "base.toml"\n[points]\nfile = "points.csv"\n')
    out = os.path.join(TMP, "sweep.csv")
    t0 = time.perf_counter()
    subprocess.run([CRADLE, "sweep", sw, "--out", out, "--backend", "cpu", "--threads", "2"],
                   check=True, capture_output=True)
    w_sweep = time.perf_counter() - t0
    rows = list(csv.DictReader(open(out)))
    e_sweep, steps_sweep = 0.0, 0
    for r, v0, sc, t in zip(rows, vs, scales, ts):
        assert r["status"] == "ok", r
        p = np.array([[float(r[f"arrival_{b}"]), float(r[f"peak_v_{b}"])] for b in PROBES])
        fin = np.array([float(r[f"v_{b}"]) for b in PROBES])
        e = error(p, None, ref, sc, t, v0)
        e = max(e, np.max(np.abs(fin - rv[PROBES] * v0 / V)) / v0)
        e_sweep = max(e_sweep, e)
        steps_sweep += int(r["steps"])
    s_part = max(1, s_eq // 16)
    wall, p, v = peer.run(N, vs, ts, s_part, PROBES)
    w_peer = wall * s_eq / s_part
    print("| code | error (the probes' peaks and final velocities only, as the rows hold them; worst chain) | wall (s) | bead-steps/s (reported runs) |")
    print("|---|---|---|---|")
    print(f"| cradle sweep --threads 2 (default tolerance, error control on) | {e_sweep:.2e} | {w_sweep:.2f} | {N * steps_sweep / w_sweep:.3e} |")
    print(f"| numba Verlet, prange, {threads} threads, {s_eq:,} steps | {e_peer_probes:.2e} (the 0.1 m/s chain at this step count; every bead: {e_peer:.2e}) | {w_peer:.1f} (extrapolated: {wall:.2f} s for {s_part:,} steps x {s_eq / s_part:.0f}) | {N * 64 * s_eq / w_peer:.3e} |")
    print(f"\nSpeed-up of the sweep: {w_peer / w_sweep:.0f}x.")


if __name__ == "__main__":
    main()
