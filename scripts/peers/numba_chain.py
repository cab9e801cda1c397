#!/usr/bin/env python3
"""The peer a physicist would write for long granular chains (issue #30): a plain
fixed-step velocity Verlet (kick-drift-kick) over every bead of an uncompressed
Hertzian chain struck at bead 0, numba @njit(parallel=True) with prange over the
chains of a sweep. It records what the engine's outcome columns hold for two probe
beads -- the leading pulse's velocity peak (time and value; the first local maximum
above 1e-3 of the striker speed, refined by a parabola through the three samples
around it) -- and every bead's final velocity.

The chain is the engine's scene (scene keys as in docs/SPEC.md Sec. 9):
  balls = N, radius = 0.005 (steel: 7850 kg/m^3, E = 200 GPa, nu = 0.3), free ends,
  bead 0 struck at v, [stop] duration = T.

Used by scripts/chain_peer_bench.py, which times it beside `cradle` at equal error;
run alone it prints its wall time for one chain:

  .venv/bin/python scripts/peers/numba_chain.py --beads 1000 --steps 2000000
"""
import argparse, math, time
import numpy as np
from numba import njit, prange

R, RHO, E, NU = 0.005, 7850.0, 200e9, 0.3
M = RHO * 4.0 / 3.0 * math.pi * R ** 3
# Hertz stiffness of two equal spheres: (4/3) E* sqrt(R*), E* = E / (2 (1 - nu^2)), R* = R/2.
K = 4.0 / 3.0 * (E / (2.0 * (1.0 - NU ** 2))) * math.sqrt(R / 2.0)
PEAK_FLOOR = 1e-3


INV_M = 1.0 / M


@njit(inline="always")
def accel(x, a, f, n):
    """Branch-free: every contact's force first (0 when open), then each
    bead's acceleration from its two contacts with a precomputed 1/m --
    what a careful physicist writes (issue #43: the first version branched
    on d > 0 and divided by the mass twice per contact, 1.03 ns per
    bead-step on one core of the project's VM against 0.46 for this one,
    the same final velocities to 5e-12)."""
    f[0] = 0.0
    f[n] = 0.0
    for i in range(1, n):
        d = max(x[i - 1] - x[i], 0.0)
        f[i] = K * d * math.sqrt(d)
    for i in range(n):
        a[i] = (f[i] - f[i + 1]) * INV_M


@njit
def one_chain(n, v0, t_end, steps, probes, peaks, v_out):
    """peaks[p] = (time, value) of probe p's first velocity maximum above the floor."""
    dt = t_end / steps
    x = np.zeros(n)
    v = np.zeros(n)
    a = np.zeros(n)
    f = np.zeros(n + 1)
    v[0] = v0
    accel(x, a, f, n)
    np_ = probes.shape[0]
    hist = np.zeros((np_, 3))  # the last three samples of each probe's velocity
    found = np.zeros(np_, np.bool_)
    for p in range(np_):
        hist[p, 2] = v[probes[p]]
        peaks[p, 0] = np.nan
        peaks[p, 1] = np.nan
    floor = PEAK_FLOOR * abs(v0)
    for k in range(1, steps + 1):
        for i in range(n):
            v[i] += 0.5 * dt * a[i]
            x[i] += dt * v[i]
        accel(x, a, f, n)
        for i in range(n):
            v[i] += 0.5 * dt * a[i]
        for p in range(np_):
            if found[p]:
                continue
            hist[p, 0] = hist[p, 1]
            hist[p, 1] = hist[p, 2]
            hist[p, 2] = v[probes[p]]
            y0, y1, y2 = hist[p, 0], hist[p, 1], hist[p, 2]
            if k >= 2 and y1 > y0 and y1 >= y2 and y1 > floor:
                # Parabola through (k-2, k-1, k): vertex offset from k-1.
                den = y0 - 2.0 * y1 + y2
                s = 0.5 * (y0 - y2) / den if den != 0.0 else 0.0
                peaks[p, 0] = (k - 1 + s) * dt
                peaks[p, 1] = y1 - 0.25 * (y0 - y2) * s
                found[p] = True
    for i in range(n):
        v_out[i] = v[i]


@njit(parallel=True)
def sweep(n, v0s, t_ends, steps, probes, peaks, v_out):
    for c in prange(v0s.shape[0]):
        one_chain(n, v0s[c], t_ends[c], steps, probes, peaks[c], v_out[c])


def run(n, v0s, t_ends, steps, probes):
    """Run the chains; returns (wall s, peaks[c, p, (t, v)], final v[c, i])."""
    v0s = np.asarray(v0s, float)
    t_ends = np.asarray(t_ends, float)
    probes = np.asarray(probes, np.int64)
    peaks = np.zeros((v0s.size, probes.size, 2))
    v_out = np.zeros((v0s.size, n))
    t0 = time.perf_counter()
    sweep(n, v0s, t_ends, steps, probes, peaks, v_out)
    return time.perf_counter() - t0, peaks, v_out


def compile_once():
    run(8, [0.1], [1e-5], 10, [2, 5])


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--beads", type=int, default=1000)
    p.add_argument("--velocity", type=float, default=0.1)
    p.add_argument("--duration", type=float, default=0.021)
    p.add_argument("--steps", type=int, default=1_000_000)
    a = p.parse_args()
    compile_once()
    probes = [a.beads // 4, 3 * a.beads // 4]
    wall, peaks, v = run(a.beads, [a.velocity], [a.duration], a.steps, probes)
    print(f"numba Verlet, {a.beads} beads, {a.steps:,} steps: {wall:.3f} s, "
          f"{a.beads * a.steps / wall:.3e} bead-steps/s; peaks {peaks[0].tolist()}")


if __name__ == "__main__":
    main()
