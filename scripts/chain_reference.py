#!/usr/bin/env python3
"""An independent reference for granular chains: scipy's DOP853 (an explicit
Runge-Kutta 8(5,3) pair with its own error control and dense output), not the
engine's composition methods, its window, kink correction or refinement.

Reads the JSON that `cargo run --release --example chain_contract` writes
(each chain's compiled beads -- masses, contact stiffnesses and rest overlaps,
initial velocities, pulse, probes -- and the engine's runs at several
tolerances), integrates each chain once with DOP853 to every run's end, and
writes the error of every run in the metric of results/chains.md: the largest
of the probes' peak times / run time, their peak velocities / v, and every
bead's final velocity / v (v the velocity scale).

The reference's own error is checked by integrating twice (rtol 1e-12 and
1e-13, both with absolute tolerances at 1e-15 of the chain's displacement and
velocity scales): the table reports that difference beside each chain; a run's
error below ~10x it is not resolved by the reference.

    python3 -m venv /tmp/ref && /tmp/ref/bin/pip install numpy scipy
    /tmp/ref/bin/python scripts/chain_reference.py target/chain_contract.json \
        --out target/chain_contract_errors.json
"""

import argparse
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
DEBUG = False



def accel(u, k, d0, f0, inv_m, v=None, gamma=0.0, drag=0.0):
    """Accelerations of the beads at displacements u (from rest, +: right)
    and velocities v.

    Contact j (0 ..= n) between bead j-1 and j (0: the left wall, n: the right
    one) has overlap d0_j + u_{j-1} - u_j; it pushes bead j right and j-1 left
    with k_j*delta^(3/2) (0 when open); f0_j is its force at rest. With a
    dashpot gamma (issue #45) a closed contact's force is
    max(0, k*delta^(3/2) + gamma*delta'), delta' = v_{j-1} - v_j (never
    pulling); the air drag adds -drag*v to every bead.
    """
    ul = np.concatenate(([0.0], u))
    ur = np.concatenate((u, [0.0]))
    d = np.maximum(d0 + ul - ur, 0.0)
    f = k * d * np.sqrt(d)
    if gamma > 0.0:
        vl = np.concatenate(([0.0], v))
        vr = np.concatenate((v, [0.0]))
        f = np.where(d > 0.0, np.maximum(f + gamma * (vl - vr), 0.0), 0.0)
    e = f - f0
    e[k == 0.0] = 0.0
    a = (e[:-1] - e[1:]) * inv_m
    if drag > 0.0:
        a = a - drag * v
    return a


def make_rhs(c, pulse_on):
    k, d0, inv_m = c["k"], c["d0"], c["inv_m"]
    f0 = np.array([kj * d * math.sqrt(d) if d > 0 else 0.0 for kj, d in zip(k, d0)])
    n = c["n"]
    p = c["pulse"]

    gamma, drag = c.get("viscosity", 0.0), c.get("air_drag", 0.0)

    def rhs(t, y):
        u, v = y[:n], y[n:]
        a = accel(u, k, d0, f0, inv_m, v, gamma, drag)
        if pulse_on and p is not None:
            a[p["bead"]] += p["force"] * math.sin(math.pi * t / p["duration"]) * inv_m[p["bead"]]
        return np.concatenate((v, a))

    return rhs


def overlaps(c, y):
    """Overlap of every contact that exists (k > 0) at state y; with
    dashpots also, per contact, where its force's kinks are: the spring plus
    dashpot force F = k*delta^(3/2) + gamma*delta' of a closed contact (its
    sign changes where the contact goes slack, never pulling), as the length
    sign(F)*|F/k|^(2/3) (1 for an open one)."""
    n = c["n"]
    u = y[:n]
    ul = np.concatenate(([0.0], u))
    ur = np.concatenate((u, [0.0]))
    d = (c["d0"] + ul - ur)[c["has"]]
    gamma = c.get("viscosity", 0.0)
    if gamma == 0.0:
        return d
    v = y[n:]
    vl = np.concatenate(([0.0], v))
    vr = np.concatenate((v, [0.0]))
    k = c["k"][c["has"]]
    dp = np.maximum(d, 0.0)
    s = (k * dp * np.sqrt(dp) + gamma * (vl - vr)[c["has"]]) / k
    s = np.sign(s) * np.abs(s) ** (2.0 / 3.0)  # (F/k)^(2/3): a length
    return np.concatenate((d, np.where(d > 0.0, s, 1.0)))


def first_zero(f, lo, hi):
    """The first t in [lo, hi] where f (> 0 at lo, <= 0 at hi) stops being
    positive: a bead's velocity maximum. brentq alone returns any exact zero
    it lands on, and a bead that flies free after its push (a gap ahead, a
    slack contact behind) has a = 0 exactly over a plateau: its maximum's
    time is the plateau's start, as the engine's observer takes it."""
    from scipy.optimize import brentq

    return brentq(lambda t: f(t) if f(t) > 0.0 else -1.0, lo, hi, xtol=1e-300, rtol=1e-15, maxiter=1000)


def integrate(c, rtol, t_ends):
    """The reference's final velocities at each of t_ends and each probe's
    local velocity maxima above the floor, in time order (time, value):
    `leading` picks the leading pulse's peak from them.

    DOP853 step by step (scipy.integrate.DOP853). The Hertz force
    k*delta^(3/2) is only C^1 where a contact opens or closes, which an
    explicit Runge-Kutta step (and its error estimate) does not see: a step
    across which some overlap changes sign is thrown away, the earliest
    crossing is located on that step's dense output (brentq), and the
    integration is restarted from the step's start to the crossing and
    then from the crossing on, so no step straddles a kink. A pulse's end
    is a restart too.
    """
    from scipy.integrate import DOP853
    from scipy.optimize import brentq

    n = c["n"]
    vs, ts = c["v_scale"], c["t_scale"]
    atol = np.concatenate((np.full(n, 1e-15 * vs * ts), np.full(n, 1e-15 * vs)))
    y = np.concatenate((np.zeros(n), np.array(c["v0"], dtype=float)))
    t_last = max(t_ends)
    floor = 1e-3 * vs
    p = c["pulse"]
    stops = sorted(set(t_ends) | ({p["duration"]} if p is not None and p["duration"] < t_last else set()))
    found = {i: [] for i in c["probes"]}
    finals = {}
    steps = restarts = 0
    t = 0.0
    rhs_on, rhs_off = make_rhs(c, True), make_rhs(c, False)
    for stop in stops:
        while t < stop:
            rhs = rhs_on if (p is not None and t < p["duration"]) else rhs_off
            solver = DOP853(rhs, t, y, stop, rtol=rtol, atol=atol)
            restarted = False
            while solver.status == "running":
                t0, y0 = solver.t, solver.y.copy()
                d0v = overlaps(c, y0)
                a0 = rhs(t0, y0)[n:]
                solver.step()
                if solver.status == "failed":
                    raise RuntimeError(f"{c['name']}: DOP853 failed at t = {t0}")
                steps += 1
                t1, y1 = solver.t, solver.y
                # Signs of every overlap at the ends and at 7 points inside
                # (a short contact can open and close within one step).
                dense = solver.dense_output()
                ts_ = t0 + (t1 - t0) * np.linspace(0.0, 1.0, 9)
                ds = np.array([d0v] + [overlaps(c, dense(x)) for x in ts_[1:-1]] + [overlaps(c, y1)])
                pos = ds > 0
                tc = t1
                # Crossings of overlaps that stay below 1e-10 of the chain's
                # length scale (a precursor's ~1e-20 m) are no kink that
                # matters: their force is (1e-10)^(3/2) of the wave's.
                big = np.abs(ds).max(axis=0) > 1e-10 * vs * ts
                for j in np.nonzero((pos[1:] != pos[:-1]).any(axis=0) & big)[0]:
                    m = int(np.nonzero(pos[1:, j] != pos[:-1, j])[0][0])
                    lo, hi = ts_[m], ts_[m + 1]
                    x = brentq(lambda tt: overlaps(c, dense(tt))[j], lo, hi, xtol=1e-300, rtol=1e-15, maxiter=1000)
                    # A crossing at the step's start (the restart's own) is no
                    # kink inside it: within 1e-9 of the step, or within what
                    # brentq resolves of the time (rtol 1e-15 of t; a restart at
                    # a root on the crossing's near side would otherwise find it
                    # again and again, ~1e-18 s on, forever).
                    if x - t0 > max(1e-9 * (t1 - t0), 64 * np.spacing(t0)):
                        tc = min(tc, x)
                if tc < t1:
                    # Redo [t0, tc] (no kink inside), then restart at tc.
                    if True:
                        seg = DOP853(rhs, t0, y0, tc, rtol=rtol, atol=atol)
                        while seg.status == "running":
                            seg.step()
                            steps += 1
                        y1, t1 = seg.y, tc
                        a1 = rhs(t1, y1)[n:]
                        for i in c["probes"]:
                            if a0[i] > 0 >= a1[i]:
                                dd = seg.dense_output() if seg.t_old is not None else None
                                if dd is not None:
                                    tp = first_zero(lambda tt: rhs(tt, dd(tt))[n + i], seg.t_old, t1)
                                    vp = dd(tp)[n + i]
                                    if vp > floor:
                                        found[i].append((tp, vp))
                    t, y = tc, y1.copy()
                    # Past the crossing by a hair: the next solver starts
                    # on the kink's far side.
                    restarts += 1
                    if restarts % 2000 == 0 and DEBUG:
                        print("restart", restarts, t, tc - t0, t1 - t0, file=sys.stderr)
                    restarted = True
                    break
                a1 = rhs(t1, y1)[n:]
                for i in c["probes"]:
                    if a0[i] > 0 >= a1[i]:
                        dense = solver.dense_output()
                        tp = first_zero(lambda tt: rhs(tt, dense(tt))[n + i], t0, t1)
                        vp = dense(tp)[n + i]
                        if vp > floor:
                            found[i].append((tp, vp))
            if not restarted:
                t, y = stop, solver.y.copy()
        if stop in t_ends:
            finals[stop] = y[n:].copy()
    return finals, found, steps + restarts


LEADING_FRACTION = 0.25  # engine::granular::observe::LEADING_FRACTION


def leading(maxima, T):
    """A probe's arrival in a run to T (docs/SPEC.md §9): the first local
    maximum at least LEADING_FRACTION of the largest up to T (time, value)."""
    seen = [m for m in maxima if m[0] <= T]
    if not seen:
        return None
    top = max(v for _, v in seen)
    return next(m for m in seen if m[1] >= LEADING_FRACTION * top)


def error(c, run, finals, found):
    """The run's error against the reference, as results/chains.md measures it."""
    vs, T = c["v_scale"], run["t_end"]
    worst = 0.0
    for pr in run["probes"]:
        ref = leading(found[pr["bead"]], T)
        eng = (pr["arrival"], pr["peak_v"])
        if ref is None and (eng[0] is None or math.isnan(eng[0])):
            continue
        if ref is None or eng[0] is None or math.isnan(eng[0]):
            return math.inf
        worst = max(worst, abs(eng[0] - ref[0]) / T, abs(eng[1] - ref[1]) / vs)
    v = np.array(run["v"], dtype=float)
    worst = max(worst, float(np.max(np.abs(v - finals[T]))) / vs)
    return worst


def one(c):
    t_ends = sorted({r["t_end"] for r in c["runs"]})
    t0 = time.time()
    cached = c.get("cached")
    if cached and all(repr(t) in cached["finals"] for t in t_ends):
        fa = {t: np.array(cached["finals"][repr(t)]) for t in t_ends}
        pa = {int(i): [tuple(m) for m in v] for i, v in cached["found"].items()}
        ref_err, steps = cached["ref_error"], cached["ref_steps"]
    else:
        fa, pa, steps = integrate(c, 1e-13, t_ends)
        fb, pb, _ = integrate(c, 1e-12, t_ends)
        # The reference's own uncertainty: rtol 1e-12 against 1e-13, in the metric.
        lb = {i: leading(pb[i], t_ends[-1]) for i in c["probes"]}
        fake = {"t_end": t_ends[-1], "v": list(fb[t_ends[-1]]), "probes": [
            {"bead": i, "arrival": lb[i][0] if lb[i] else float("nan"),
             "peak_v": lb[i][1] if lb[i] else float("nan")} for i in c["probes"]]}
        ref_err = error(c, fake, fa, pa)
    secs = time.time() - t0
    out = []
    for r in c["runs"]:
        out.append({"tol": r["tol"], "kind": r["kind"], "error": error(c, r, fa, pa)})
    return {"name": c["name"], "ref_error": ref_err, "ref_steps": steps,
            "ref_seconds": secs, "runs": out,
            "reference": {"finals": {repr(t): list(map(float, fa[t])) for t in t_ends},
                          "found": {str(i): [list(map(float, m)) for m in v] for i, v in pa.items()},
                          "ref_error": ref_err, "ref_steps": steps}}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("input")
    ap.add_argument("--out", required=True)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", help="chains whose name contains this")
    ap.add_argument("--reuse", help="an earlier output of this script: its references are reused "
                    "for the chains and run ends it has (the engine's runs are measured afresh)")
    a = ap.parse_args()
    chains = json.load(open(a.input))["chains"]
    if a.only:
        chains = [c for c in chains if a.only in c["name"]]
    old = {}
    if a.reuse:
        old = {c["name"]: c.get("reference") for c in json.load(open(a.reuse))["chains"]}
    for c in chains:
        c["cached"] = old.get(c["name"])
        c["k"] = np.array(c["k"], dtype=float)
        c["has"] = c["k"] > 0
        c["d0"] = np.array(c["d0"], dtype=float)
        c["inv_m"] = 1.0 / np.array(c["mass"], dtype=float)
    with ProcessPoolExecutor(a.jobs) as ex:
        res = list(ex.map(one, chains))
    for r in res:
        print(f"{r['name']}: reference self-difference {r['ref_error']:.2e}, "
              f"{r['ref_steps']} steps, {r['ref_seconds']:.1f} s", file=sys.stderr)
    json.dump({"chains": res}, open(a.out, "w"), indent=1)


if __name__ == "__main__":
    main()
