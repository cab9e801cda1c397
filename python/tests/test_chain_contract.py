"""The tolerance contract on chains (docs/SPEC.md §9, "Error control")
against an independent reference: scipy's DOP853 with every contact's
opening and closing located (scripts/chain_reference.py), not the engine at
a finer step. A 60-bead dimer R 5 / 1.9 mm against a wall, whose light beads
rattle — a chain unlike the step rule's fit, on which the step rule alone
missed its tolerance by up to 54x: each row meets its tolerance or says it
does not, and its error_estimate is at least a third of its true error."""

import math
import sys
from pathlib import Path

import numpy as np

import hertz_cradle as hc

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))
import chain_reference as ref  # noqa: E402

N, V, T = 60, 0.1, 1.5e-3
RADII = [0.005, 0.0019] * (N // 2)
E, NU, RHO = 200e9, 0.3, 7850.0
PROBES = [10, 50]


def stiffness(r1, r2):
    """engine::contact::hertz_stiffness for two steel bodies (r2 = inf: a wall)."""
    e_star = 1.0 / (2.0 * (1.0 - NU * NU) / E)
    r_star = r1 if math.isinf(r2) else r1 * r2 / (r1 + r2)
    return 4.0 / 3.0 * e_star * math.sqrt(r_star)


def chain():
    mass = np.array([RHO * 4.0 / 3.0 * math.pi * r ** 3 for r in RADII])
    k = np.zeros(N + 1)
    for j in range(1, N):
        k[j] = stiffness(RADII[j - 1], RADII[j])
    k[N] = stiffness(RADII[N - 1], math.inf)
    v0 = np.zeros(N)
    v0[0] = V
    return {"name": "dimer", "n": N, "k": k, "has": k > 0, "d0": np.zeros(N + 1),
            "inv_m": 1.0 / mass, "v0": v0, "pulse": None, "probes": PROBES,
            "v_scale": V, "t_scale": 1e-5}


def test_dimer_rows_meet_their_tolerance_against_dop853(tmp_path):
    scene = tmp_path / "dimer.toml"
    scene.write_text(f"balls = {N}\nradius = 0.005\n[pattern]\nradius = [0.005, 0.0019]\n"
                     f"[walls]\nright = true\n[launch]\nballs = 1\nvelocity = {V}\n"
                     f"[probes]\nbeads = {PROBES}\n[stop]\nduration = {T}\n")
    c = chain()
    finals, maxima, _ = ref.integrate(c, 1e-13, [T])
    finals12, maxima12, _ = ref.integrate(c, 1e-12, [T])
    # Each probe's leading pulse's peak (docs/SPEC.md §9), as the engine
    # defines a probe's arrival.
    found = {b: ref.leading(maxima[b], T) for b in PROBES}
    found12 = {b: ref.leading(maxima12[b], T) for b in PROBES}

    def error(row_v, peaks, fin, fnd):
        e = float(np.max(np.abs(np.array(row_v) - fin[T]))) / V
        for b, (t, v) in zip(PROBES, peaks):
            assert fnd[b] is not None and not math.isnan(t), b
            e = max(e, abs(t - fnd[b][0]) / T, abs(v - fnd[b][1]) / V)
        return e

    ref_err = error(finals12[T], [found12[b] for b in PROBES], finals, found)
    assert ref_err < 1e-8, ref_err
    checked = 0
    for tol in (1e-4, 1e-6):
        row = hc.run(str(scene), tolerance=tol)
        v = [row[f"v_{i}"] for i in range(N)]
        peaks = [(row[f"arrival_{b}"], row[f"peak_v_{b}"]) for b in PROBES]
        e = error(v, peaks, finals, found)
        est = row["error_estimate"]
        assert row["status"] in ("ok", "inaccurate", "sensitive"), row["status"]
        if row["status"] == "ok":
            assert e <= tol + ref_err, (tol, e, est)
        else:
            assert est > tol
        if e > 10 * ref_err:
            checked += 1
            assert est >= e / 3, (tol, e, est)
    # The estimate was checked against a resolved error at least once.
    assert checked > 0
