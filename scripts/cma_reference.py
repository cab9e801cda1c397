#!/usr/bin/env python3
"""Hansen's reference CMA-ES (pycma) on the 10-D sphere and Rosenbrock: the
evaluations it takes to reach f < 1e-10 from the same start, sigma0 = 0.5
and its default population (10), over seeds 1-20. The unit test
`optimize::cmaes::tests::finds_the_sphere_and_rosenbrock_minima` holds the
engine's CMA-ES to these medians within 30%.

    python3 -m venv /tmp/cma && /tmp/cma/bin/pip install cma numpy
    /tmp/cma/bin/python scripts/cma_reference.py
"""
import cma
import numpy as np


def evaluations(f, x0, sigma, target, seed):
    es = cma.CMAEvolutionStrategy(x0, sigma, {
        "seed": seed, "verbose": -9, "ftarget": target, "maxfevals": 1e6,
        "tolfun": 0, "tolx": 0, "tolfunhist": 0})
    used = 0
    while True:
        xs = es.ask()
        fs = [f(np.array(x)) for x in xs]
        used += len(xs)
        if min(fs) < target:
            return used
        es.tell(xs, fs)


def sphere(x):
    return float((x ** 2).sum())


def rosenbrock(x):
    return float(sum(100 * (x[1:] - x[:-1] ** 2) ** 2 + (1 - x[:-1]) ** 2))


for name, f, x0 in [("sphere", sphere, [1.0] * 10), ("rosenbrock", rosenbrock, [0.1] * 10)]:
    r = [evaluations(f, x0, 0.5, 1e-10, s) for s in range(1, 21)]
    print(f"{name}: pycma {cma.__version__}, median {int(np.median(r))}, min {min(r)}, max {max(r)}")
