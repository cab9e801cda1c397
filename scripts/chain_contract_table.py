#!/usr/bin/env python3
"""The tables of results/chains.md's "tolerance contract" section, from the
engine's runs (examples/chain_contract.rs) and their true errors against the
independent reference (scripts/chain_reference.py).

    python3 scripts/chain_contract_table.py target/chain_contract.json \
        target/chain_contract_errors.json

With --backends (the runs of `chain_contract --backend … --precision …`):
one row per backend, precision and tolerance (met / flagged / silent).

A run is *met* when its status is ok and its error against the reference is
within its tolerance, *flagged* when its status is inaccurate or sensitive,
*silent* when its status is ok and its error is above its tolerance (what the
contract forbids). Errors the reference does not resolve (below 10x its own
rtol 1e-12 vs 1e-13 difference) count as met when the run says ok.
"""

import json
import math
import statistics
import sys



def difference(vs, a, b):
    """engine::granular::control::difference."""
    t = a["t_end"]
    d = 0.0
    for p, q in zip(a["probes"], b["probes"]):
        na, nb = p["arrival"] is None, q["arrival"] is None
        if na and nb:
            continue
        if na != nb:
            return math.inf
        d = max(d, abs(p["arrival"] - q["arrival"]) / t, abs(p["peak_v"] - q["peak_v"]) / vs)
    for x, y in zip(a["v"], b["v"]):
        d = max(d, abs(x - y) / vs)
    return d


def verdict(r, t, floor):
    """met, flagged (inaccurate or sensitive), unresolved (the reference's
    own error, floor/10, above the tolerance: it cannot tell) or silent
    (every other row: the contract's failure)."""
    if r["status"] in ("inaccurate", "sensitive"):
        return "flagged"
    if floor > t:
        return "unresolved"
    if r["status"] == "ok" and (r["error"] <= t or r["error"] <= floor):
        return "met"
    return "silent"


def backends(eng_path, err_path):
    """The contract per backend and precision."""
    doc = json.load(open(eng_path))
    err = {c["name"]: c for c in json.load(open(err_path))["chains"]}
    tally = {}
    silent = []
    for c in doc["chains"]:
        e = err[c["name"]]
        floor = 10 * e["ref_error"]
        for r, x in zip(c["runs"], e["runs"]):
            key = (r["backend"], r["precision"], r["tol"])
            a = tally.setdefault(key, {"met": 0, "flagged": 0, "silent": 0, "unresolved": 0, "ratios": [], "steps": []})
            v = verdict(dict(r, error=x["error"]), r["tol"], floor)
            a[v] += 1
            a["steps"].append(r["steps"])
            if v == "silent":
                silent.append(f"{c['name']}, {key}: error {x['error']:.2e}, estimate {r['estimate']}")
            est = r["estimate"]
            if est is not None and x["error"] > floor and x["error"] > 0:
                a["ratios"].append(est / x["error"])
    print(f"Adapter: {doc.get('adapter') or 'none (CPU only)'}")
    print()
    print("| backend | precision | tolerance | met | flagged | silent | unresolved by the reference | estimate / true error: min, median | steps: median |")
    print("|---|---|---|---|---|---|---|---|---|")
    for (b, p, t), a in tally.items():
        rs = a["ratios"] or [math.nan]
        print(f"| {b} | {p} | {t:g} | {a['met']} | {a['flagged']} | {a['silent']} | {a['unresolved']} "
              f"| {min(rs):.2f}, {statistics.median(rs):.2f} | {statistics.median(a['steps']):.0f} |")
    for x in silent:
        print(f"- silent: {x}")


def main():
    if "--backends" in sys.argv:
        args = [a for a in sys.argv[1:] if a != "--backends"]
        return backends(args[0], args[1])
    eng = json.load(open(sys.argv[1]))["chains"]
    err = {c["name"]: c for c in json.load(open(sys.argv[2]))["chains"]}
    tols = [1e-4, 1e-6, 1e-8]
    rows = []
    tally = {t: {"met": 0, "flagged": 0, "silent": 0, "unresolved": 0, "ratios": [], "cost": [], "time": []} for t in tols}
    pairs = []
    low = []
    for c in eng:
        e = err.get(c["name"])
        if e is None:
            continue
        floor = 10 * e["ref_error"]
        for r, x in zip(c["runs"], e["runs"]):
            r["error"] = x["error"]
        by = {}
        for r in c["runs"]:
            if r["kind"] in ("controlled", "plain"):
                by[(r["kind"], r["tol"])] = r
        cells = []
        for t in tols:
            r, p = by[("controlled", t)], by[("plain", t)]
            v = verdict(r, t, floor)
            tally[t][v] += 1
            # The cell names the status where the tally's word would hide it.
            label = {
                "flagged": r["status"],
                "unresolved": "unresolved (" + r["status"] + ")",
                "met": "met",
                "silent": "SILENT" if r["status"] == "ok" else r["status"],
            }[v]
            est = r["estimate"]
            if est is not None and r["error"] > floor and r["error"] > 0:
                tally[t]["ratios"].append(est / r["error"])
                if est < r["error"] / 3:
                    low.append(f"{c['name']} at {t:g}: estimate {est:.2e}, error {r['error']:.2e}")
            tally[t]["cost"].append(r["bead_steps"] / p["bead_steps"])
            tally[t]["time"].append(r["seconds"] / max(p["seconds"], 1e-9))
            cells.append(f"{label} {r['error']:.1e} / {est if est is not None else float('nan'):.1e} "
                         f"(plain {p['error']:.1e})")
        rows.append(f"| {c['name']} | {e['ref_error']:.1e} | " + " | ".join(cells) + " |")
        # Calibration pairs: the run at each first guess against its twin
        # with the refinement forced on ("coarse") and without ("mixed").
        pr = {}
        for r in c["runs"]:
            if r["kind"] == "pair":
                pr.setdefault(r["pair"], {})[r["role"]] = r
        seen = set()
        fine_from = c["t_scale"] / 90 * (1 + 1e-9)  # engine::granular::REFINE_FROM
        for v in pr.values():
            f = v["fine"]
            if f["h"] in seen or f["status"] != "ok" or f["error"] <= floor:
                continue
            seen.add(f["h"])
            fr = f["h"] <= fine_from
            for role in ("coarse", "mixed"):
                co = v[role]
                cr = co["h"] <= fine_from or (role == "coarse" and fr)
                kind = ("R" if fr else "U") + ("R" if cr else "U")
                if role == "coarse" and kind == "UU":
                    continue  # the same runs as "mixed"
                d = difference(c["v_scale"], f, co)
                pairs.append((c["name"], kind, co["h"] / f["h"], d, f["error"]))
    print("| chain | reference's own error | tol 1e-4: verdict, error / estimate (plain run's error) | tol 1e-6 | tol 1e-8 |")
    print("|---|---|---|---|---|")
    print("\n".join(rows))
    print()
    print("| tolerance | met | flagged | silent | unresolved by the reference | estimate / true error: min, median | bead-steps / the plain run's: median, max | time / the plain run's: median |")
    print("|---|---|---|---|---|---|---|---|")
    for t in tols:
        a = tally[t]
        rs = a["ratios"] or [math.nan]
        print(f"| {t:g} | {a['met']} | {a['flagged']} | {a['silent']} | {a['unresolved']} | {min(rs):.2f}, {statistics.median(rs):.2f} "
              f"| {statistics.median(a['cost']):.2f}, {max(a['cost']):.2f} | {statistics.median(a['time']):.2f} |")
    for x in low:
        print(f"- estimate below a third of the error: {x}")
    print()
    print("Calibration: the estimate diff/(r^q - 1) over the true error of the finer run of each pair "
          "whose error the reference resolves; U: a run without the local refinement, R: with it "
          "(fine, coarse)")
    print()
    print("| pair | pairs | q = 1 | 2 | 3 | 4 | 5 | 6 | 6.2 |")
    print("|---|---|---|---|---|---|---|---|---|")
    for kind in ("UU", "RR", "RU"):
        for dmax in (math.inf, 1e-3):
            sel = [p for p in pairs if p[1] == kind and p[3] <= dmax]
            if not sel:
                continue
            cells = []
            for q in (1, 2, 3, 4, 5, 6, 6.2):
                rs = sorted(d / (r ** q - 1) / e for (_, _, r, d, e) in sel)
                cells.append(f"{rs[0]:.2f} ({sum(x < 1 / 3 for x in rs)})")
            label = kind + ("" if dmax == math.inf else ", differing by < 1e-3")
            print(f"| {label} | {len(sel)} | " + " | ".join(cells) + " |")
    print()
    print("Each cell: the smallest estimate / true error, and (in brackets) the pairs below 1/3.")


if __name__ == "__main__":
    main()
