"""Fit the chain step rule's error model (granular::chain_error_model): error ~
C*(h/t_s)^q*(T/t_s), relative to the striker speed, on uniform steel chains
(R = 5 mm) of N beads struck at bead 0 at 0.1 m/s, run to 0.76 of their default
end (the wave ~70% along the chain, where a phase error shows most in the final
velocities), at given steps h = t_s/n (n = 20 to 2560, five an octave: a kink's
error depends on where in its step the contact crosses, so the error scatters
about its trend with h and an envelope needs many points). Error: the largest
of the probes' (N/4, 3N/4) velocity-peak times / run time and values / v, and
every bead's final velocity / v, against kahanli6 at t_s/16000.

Steps at or below t_s/90 (granular::REFINE_FROM) run with the local refinement
(step::Refine; kahanli6 and suzuki4), coarser ones without: the two are fitted
apart. Prints each chain's table, then each method's model over all chains: q by
least squares of log(error/T) against log(h/t_s), C the envelope of every point
times a margin of 3 — without the refinement what granular::chain_error_model
holds, with it granular::refined_error_model. Errors below 1e-10 without the
refinement (f64's round-off over millions of steps, not the step's) and below
5e-11 with it (where the 1,000-bead chain's errors level off: round-off over its
10^5-10^6 steps) are left out of both.

    python3 scripts/chain_error_fit.py [CRADLE] [N ...]   (default target/release/cradle 200 1000)"""
import csv, io, math, os, subprocess, sys, tempfile

C = sys.argv[1] if len(sys.argv) > 1 else "target/release/cradle"
CHAINS = [int(n) for n in sys.argv[2:]] or [200, 1000]
V = 0.1
MARGIN = 3.0
# Errors below this are f64's round-off over millions of steps (and the
# reference's own), not the step's: left out of the fit (marked in the table).
FLOOR = 1e-10
REFINED_FLOOR = 5e-11
REFINE_FROM = 90
# The methods the refinement is for (granular::refined_error_model). yoshida4's
# error is its smooth part's, and the refinement raised it (old/new error 0.6-0.7,
# geometric mean over these steps); yoshida6's is dominated by spikes at some
# steps (10-100x its neighbours', as built too), which leave its refined fit at
# q ~ 1: both run without.
REFINED = ("kahanli6", "suzuki4")
FINE = [20 * 2 ** (k / 5) for k in range(36)]
METHODS = [("kahanli6", FINE), ("yoshida6", FINE), ("yoshida4", FINE), ("suzuki4", FINE),
           ("verlet", FINE[5:])]
tmp = tempfile.mkdtemp()


def base(n):
    return f"""balls = {n}
radius = 0.005
[launch]
balls = 1
velocity = {V}
[probes]
beads = [{n // 4}, {3 * n // 4}]
[record]
stride = 1
every = 1.0
"""


def run(text):
    path = os.path.join(tmp, "c.toml")
    with open(path, "w") as f:
        f.write(text)
    tr = os.path.join(tmp, "t.csv")
    out = subprocess.run([C, "run", path, "--format", "csv", "--trace", tr],
                         capture_output=True, text=True, check=True).stdout
    head, row = list(csv.reader(io.StringIO(out)))[:2]
    o = {k: float(v) if v not in ("", "ok") else v for k, v in zip(head, row)}
    rows = list(csv.reader(open(tr)))
    last = dict(zip(rows[0], rows[-1]))
    o["v"] = [float(last[k]) for k in rows[0] if k.startswith("v_")]
    return o


def error(o, r, n):
    e = max(abs(a - b) for a, b in zip(o["v"], r["v"])) / V
    for p in (n // 4, 3 * n // 4):
        e = max(e, abs(o[f"arrival_{p}"] - r[f"arrival_{p}"]) / r["t_end"],
                abs(o[f"peak_v_{p}"] - r[f"peak_v_{p}"]) / V)
    return e


def chain(n):
    """Points (h/t_s, error/T) per method on the n-bead chain, its table printed."""
    loose = run(base(n) + "[solver]\ntolerance = 0.5\n")
    ts = 20 * loose["dt"]  # the rule's cap, h = t_s/20, at a loose tolerance
    text = base(n) + f"[stop]\nduration = {0.76 * loose['t_end']!r}\n[solver]\n"
    ref = run(text + f"dt = {ts / 16000!r}\nmethod = \"kahanli6\"\n")
    T = ref["t_end"] / ts
    print(f"## {n} beads\n\nt_s = {ts:.6e} s, run T = {T:.1f} t_s, "
          f"reference kahanli6 at t_s/16000 ({ref['steps']:.0f} steps)\n")
    print("| method | h | refined | error | local order |")
    print("|---|---|---|---|---|")
    pts = {}
    for method, ns in METHODS:
        got = pts.setdefault(method, [])
        for k in ns:
            o = run(text + f"dt = {ts / k!r}\nmethod = \"{method}\"\n")
            refined = method in REFINED and k >= REFINE_FROM
            got.append((o["dt"] / ts, error(o, ref, n) / T, T, refined))
            (x1, e1, _, _), (x0, e0, _, _) = got[-1], got[-2] if len(got) > 1 else (None,) * 4
            order = "" if x0 is None else f"{math.log(e0 / e1) / math.log(x0 / x1):.2f}"
            mark = " (floor)" if e1 * T < (REFINED_FLOOR if refined else FLOOR) else ""
            note = "yes" if refined else ""
            print(f"| {method} | t_s/{k:.1f} | {note} | {e1 * T:.2e}{mark} | {order} |",
                  flush=True)
    print()
    return pts


def fit(pts, floor):
    """q by least squares, C the envelope of (x, e/T, T) points, those with
    e below `floor` left out."""
    pts = [(x, y) for x, y, t in pts if y * t >= floor]
    if len(pts) < 2:
        return float("nan"), float("nan")
    xs = [math.log(x) for x, _ in pts]
    ys = [math.log(y) for _, y in pts]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    q = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    return max(y / x ** q for x, y in pts), q


if __name__ == "__main__":
    every = [chain(n) for n in CHAINS]
    print(f"## The model over {', '.join(map(str, CHAINS))} beads\n")
    print("| method | steps | points | q | envelope C | C with the margin (x3) |")
    print("|---|---|---|---|---|---|")
    for method, _ in METHODS:
        coarse = f"coarser than t_s/{REFINE_FROM}" if method in REFINED else "all"
        for refined, floor, where in ((False, FLOOR, coarse),
                                      (True, REFINED_FLOOR, f"t_s/{REFINE_FROM} and finer, refined")):
            pts = [p[:3] for pts in every for p in pts[method] if p[3] == refined]
            if not pts:
                continue
            c, q = fit(pts, floor)
            used = sum(1 for _, y, t in pts if y * t >= floor)
            print(f"| {method} | {where} | {used} | {q:.2f} | {c:.3g} | {MARGIN * c:.3g} |")
