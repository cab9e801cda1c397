"""Convergence order of the chain engine on a chain driven by a force pulse
(results/chains.md): a precompressed 60-bead steel chain (10 N, both walls)
with a 0.5 N x 20 us half-sine pulse at bead 0, run 0.3 ms with a given
[solver] dt = tau/n (n = 10, 20, 40, 80, and n + 0.5: steps that do not
divide tau, which the plan shrinks onto it), against kahanli6 at tau/4000.
Error: the largest |v_i - v_i,ref| over the 60 final velocities / max |v_ref|.

    python3 scripts/chain_pulse_order.py [CRADLE]   (default target/release/cradle)"""
import csv, io, math, os, subprocess, sys, tempfile

C = sys.argv[1] if len(sys.argv) > 1 else "target/release/cradle"
BASE = """balls = 60
radius = 0.005
[walls]
left = true
right = true
precompression = 10.0
[pulse]
bead = 0
force = 0.5
duration = 2e-5
[probes]
beads = [10, 50]
[stop]
duration = 3e-4
"""
TAU = 2e-5
tmp = tempfile.mkdtemp()


def run(dt, method):
    path = os.path.join(tmp, "pulse.toml")
    with open(path, "w") as f:
        f.write(BASE + f"[solver]\ndt = {dt!r}\nmethod = \"{method}\"\n")
    out = subprocess.run([C, "run", path, "--format", "csv"], capture_output=True, text=True, check=True).stdout
    head, row = list(csv.reader(io.StringIO(out)))[:2]
    row = dict(zip(head, row))
    return [float(row[f"v_{i}"]) for i in range(60)], float(row["dt"])


ref, _ = run(TAU / 4000, "kahanli6")
scale = max(abs(x) for x in ref)
print("| method | dt asked | steps to tau | error | order |")
print("|---|---|---|---|---|")
for method in ["kahanli6", "yoshida4", "verlet"]:
    for shift in (0.0, 0.5):
        prev = None
        for n in (10, 20, 40, 80):
            v, h = run(TAU / (n + shift), method)
            err = max(abs(a - b) for a, b in zip(v, ref)) / scale
            order = "" if prev is None else f"{math.log(prev[1] / err) / math.log(prev[0] / h):.2f}"
            print(f"| {method} | tau/{n + shift:g} | {TAU / h:.0f} | {err:.2e} | {order} |")
            prev = (h, err)
