#!/usr/bin/env python3
"""Summarise results/stress.csv (the stress envelope sweep) as Markdown:
ok fraction and worst conservation errors per region, and every non-ok status.

  python3 scripts/stress_summary.py results/stress.csv
"""
import collections, csv, math, sys

STEEL = 7850 * 4 / 3 * math.pi * 0.0125 ** 3


def main(path):
    rows = list(csv.DictReader(open(path)))
    groups = collections.OrderedDict()
    statuses = collections.Counter(r["status"] for r in rows)

    def add(key, r):
        g = groups.setdefault(key, {"n": 0, "ok": 0, "mom": 0.0, "en": 0.0})
        g["n"] += 1
        if r["status"] == "ok":
            g["ok"] += 1
            g["mom"] = max(g["mom"], float(r["momentum_error"]))
            g["en"] = max(g["en"], float(r["energy_error"]))

    for r in rows:
        ratio = float(r["mass[1]"]) / STEEL
        add(f"balls = {r['balls']}", r)
        add(f"mass ratio {ratio:.0e}", r)
        add(f"speed {float(r['launch.velocity']):.0e} m/s", r)
        add(f"E = {float(r['young_modulus']):.0e} Pa", r)
        add(f"gap = {float(r['gap']):.0e} m", r)
    print(f"{len(rows)} scenes: " + ", ".join(f"{k} {v}" for k, v in statuses.most_common()))
    print()
    print("| region | scenes | ok | worst momentum error (ok) | worst energy error (ok) |")
    print("|---|---|---|---|---|")
    for k, g in groups.items():
        print(f"| {k} | {g['n']} | {100 * g['ok'] / g['n']:.1f}% | {g['mom']:.1e} | {g['en']:.1e} |")


if __name__ == "__main__":
    main(sys.argv[1])
