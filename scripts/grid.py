"""A mass x gap sweep of the 5-ball steel cradle at any resolution (the grid100 ranges; grid1000 is the throughput benchmark of issue #17):
python3 grid.py NF NG > sweep.toml. Scene id = f_index*NG + g_index."""
import sys
nf, ng = int(sys.argv[1]), int(sys.argv[2])
M = 0.06422266231947886
print(f"""[scene]
balls = 5
radius = 0.0125
density = 7850.0
young_modulus = 200e9
poisson_ratio = 0.3
velocity = [1.0, 0.0, 0.0, 0.0, 0.0]

[[axis]]
param = "mass[2]"
logspace = [{M/10!r}, {M*10!r}, {nf}]

[[axis]]
param = "gap"
linspace = [0.0, 2e-5, {ng}]
""")
