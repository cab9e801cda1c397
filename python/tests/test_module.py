"""The Python module against the command line: same physics, same values,
same errors; dict specs, interrupts, Parquet through pyarrow/pandas/polars.

Needs the module installed (`pip install ./python`) and a `cradle` binary
(CRADLE_BIN, else target/release/cradle or target/debug/cradle)."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import hertz_cradle as hc

ROOT = Path(__file__).resolve().parents[2]
MASS_GAP = ROOT / "examples" / "mass_gap.toml"


def cradle_bin():
    env = os.environ.get("CRADLE_BIN")
    if env:
        return env
    for p in ("target/release/cradle", "target/debug/cradle"):
        if (ROOT / p).exists():
            return str(ROOT / p)
    pytest.skip("no cradle binary: build it (cargo build) or set CRADLE_BIN")


def cli(*args, cwd=None):
    return subprocess.run([cradle_bin(), *map(str, args)], capture_output=True, text=True, cwd=cwd)


SMALL = {
    "description": "a 3 x 4 sweep",
    "scene": {"balls": 5, "velocity": [1.0, 0.0, 0.0, 0.0, 0.0]},
    "axis": [
        {"param": "mass[2]", "logspace": [0.01, 0.5, 3]},
        {"param": "gap", "linspace": [0.0, 2e-5, 4]},
    ],
}
SMALL_TOML = textwrap.dedent(
    """\
    description = "a 3 x 4 sweep"
    [scene]
    balls = 5
    velocity = [1.0, 0.0, 0.0, 0.0, 0.0]
    [[axis]]
    param = "mass[2]"
    logspace = [0.01, 0.5, 3]
    [[axis]]
    param = "gap"
    linspace = [0.0, 2e-5, 4]
    """
)


def test_sweep_writes_the_clis_bytes_and_returns_its_values(tmp_path):
    ref = tmp_path / "cli.csv"
    r = cli("sweep", MASS_GAP, "--out", ref, "--backend", "cpu")
    assert r.returncode == 0, r.stderr
    mine = tmp_path / "py.csv"
    table = hc.sweep(MASS_GAP, backend="cpu", out=mine, progress=False)
    assert mine.read_bytes() == ref.read_bytes()
    assert json.loads((tmp_path / "py.csv.json").read_text())["ids"] == [0, 10000]
    # The returned table: the CSV's columns, typed, the CLI's Parquet values.
    ref_pq = tmp_path / "cli.parquet"
    assert cli("sweep", MASS_GAP, "--out", ref_pq, "--backend", "cpu").returncode == 0
    want = pq.read_table(ref_pq)
    assert table.equals(want)
    assert table.column_names == ref.read_text().splitlines()[0].split(",")
    assert table.schema.field("id").type == pa.int64()
    assert table.schema.field("ejected").type == pa.int64()
    assert pa.types.is_dictionary(table.schema.field("status").type)
    # In memory (no out=): the same table, nothing left behind.
    assert hc.sweep(str(MASS_GAP), backend="cpu", progress=False, threads=1).equals(want)


def test_a_dict_a_toml_string_and_a_file_are_the_same_sweep(tmp_path):
    f = tmp_path / "small.toml"
    f.write_text(SMALL_TOML)
    a = hc.sweep(f, backend="cpu", progress=False)
    b = hc.sweep(SMALL_TOML, backend="cpu", progress=False)
    c = hc.sweep(SMALL, backend="cpu", progress=False)
    assert a.num_rows == 12 and a.equals(b) and a.equals(c)
    assert a.column("gap").to_pylist()[:4] == [0.0, 2e-5 / 3, 2 * 2e-5 / 3, 2e-5]
    # A path whose folder holds a `=` is a path, not TOML text (it was read
    # as TOML and failed).
    run = tmp_path / "v=0.1"
    run.mkdir()
    (run / "sweep.toml").write_text(SMALL_TOML)
    assert hc.sweep(str(run / "sweep.toml"), backend="cpu", progress=False).equals(a)


def test_progress_is_a_callable_that_sees_every_scene_and_can_stop_the_sweep(tmp_path):
    # Told (done, total) as the count moves, from the calling thread, ending
    # at every scene: what a notebook feeds to tqdm.
    seen = []
    t = hc.sweep(MASS_GAP, backend="cpu", threads=1, progress=lambda d, n: seen.append((d, n)))
    assert seen and seen[-1] == (t.num_rows, t.num_rows)
    assert all(n == t.num_rows for _, n in seen)
    assert [d for d, _ in seen] == sorted({d for d, _ in seen})
    # An exception in it stops the sweep and reaches the caller.
    def stop(done, total):
        raise RuntimeError(f"stop at {done} of {total}")

    with pytest.raises(RuntimeError, match="stop at"):
        hc.sweep(MASS_GAP, backend="cpu", progress=stop, out=tmp_path / "m.csv")
    # The default bar draws only where someone sees it: not into a pipe.
    assert hc._bar(open(os.devnull, "w")) is None


def test_bad_input_raises_value_error_with_the_clis_message(tmp_path):
    bad = dict(SMALL, axis=[{"param": "gap", "linspace": [0.0, 2e-5, 0]}])
    with pytest.raises(ValueError, match="at least 1 point"):
        hc.sweep(bad, progress=False)
    f = tmp_path / "bad.toml"
    f.write_text(SMALL_TOML.replace('"gap"', '"gapp"'))
    r = cli("sweep", f, "--out", tmp_path / "x.csv")
    assert r.returncode == 2
    with pytest.raises(ValueError) as e:
        hc.sweep(f, out=tmp_path / "y.csv", progress=False)
    assert str(e.value) == r.stderr.strip().removeprefix("error: ")
    assert "gapp" in str(e.value) and "bad.toml" in str(e.value)
    with pytest.raises(ValueError, match="--tolerance"):
        hc.sweep(SMALL, tolerance=-1, progress=False)
    with pytest.raises(ValueError, match="possible values"):
        hc.sweep(SMALL, backend="quantum", progress=False)
    with pytest.raises(ValueError, match="no such file, nor a built-in scene"):
        hc.run("no-such-scene")
    with pytest.raises(TypeError):
        hc.sweep(42)
    assert not (tmp_path / "y.csv").exists()


def test_run_equals_cradle_run(tmp_path):
    r = cli("run", "cradle-2", "--format", "csv")
    header, row = r.stdout.splitlines()
    want = dict(zip(header.split(","), row.split(",")))
    got = hc.run("cradle-2")
    assert got["status"] == want["status"] == "ok"
    for k, v in want.items():
        if k in ("id",):
            continue
        if v == "":
            assert got[k] is None, k
        elif k in ("ejected", "steps", "contacts"):
            assert got[k] == int(v), k
        elif k != "status":
            assert got[k] == float(v), k  # the CLI's text is the shortest round trip
    assert set(hc.scenes()) >= {"cradle-1", "cradle-2", "seed-glued-pair-into-one"}
    # A scene as a dict, with a trace.
    scene = {"balls": 2, "velocity": [1.0, 0.0]}
    out, trace = hc.run(scene, trace_dt=2e-6)
    assert out["status"] == "ok" and trace.column_names == ["t", "x_0", "x_1", "v_0", "v_1"]
    assert abs(out["v_1"] - 1.0) < 1e-9 and abs(out["v_0"]) < 1e-9
    assert trace.num_rows > 10
    assert hc.run(scene, model="hard-sphere")["v_1"] == 1.0


def test_a_granular_chain_runs_as_cradle_run_does(tmp_path):
    scene = tmp_path / "chain.toml"
    scene.write_text("balls = 100\nradius = 0.005\n[walls]\nright = true\n"
                     "[launch]\nballs = 1\nvelocity = 0.1\n[probes]\nbeads = [20, 80]\n"
                     "[record]\nstride = 10\nevery = 1e-4\n")
    header, row = cli("run", str(scene), "--format", "csv").stdout.splitlines()
    want = dict(zip(header.split(","), row.split(",")))
    got = hc.run(str(scene))
    assert got["status"] == want["status"] == "ok"
    for k, v in want.items():
        if v == "":
            assert got[k] is None, k
        elif k in ("fragments", "steps"):
            assert got[k] == int(v), k
        elif k != "status":
            assert got[k] == float(v), k
    assert got["arrival_80"] > got["arrival_20"] > 0
    # Every chain row carries its error estimate, within the tolerance when ok.
    assert 0 < got["error_estimate"] <= 1e-6
    # The [record] beads' histories as a Table.
    out, trace = hc.run(str(scene), trace=True)
    # (the step divides the trace's spacing: the same run to the tolerance)
    assert out["status"] == "ok" and abs(out["arrival_80"] / got["arrival_80"] - 1) < 1e-6
    assert trace.column_names[:4] == ["t", "x_0", "x_10", "x_20"] and "f_wall_right" in trace.column_names
    # In df64 (pairs of f32) the chain gives the same wave to ~1e-12; f32 is refused.
    pair = hc.run(str(scene), precision="df64")
    assert pair["status"] == "ok" and pair["steps"] == got["steps"]
    for k in ("arrival_20", "arrival_80", "peak_v_80", "wall_right_peak_force"):
        assert abs(pair[k] / got[k] - 1) < 1e-9, k
    with pytest.raises(ValueError, match="f64 or df64"):
        hc.run(str(scene), precision="f32")


def test_a_dissipating_pushed_and_driven_chain_from_python(tmp_path):
    """Issue #45 from Python: the same row as `cradle run` for a chain with
    dashpots and a piston, and for a driven one, with their columns."""
    pushed = tmp_path / "pushed.toml"
    pushed.write_text("balls = 60\nradius = 0.005\n[walls]\nleft = true\n[piston]\nvelocity = 0.1\n"
                      "[damping]\nviscosity = 20.0\n[probes]\nbeads = [10, 50]\n"
                      "[stop]\nduration = 1.5e-3\n")
    driven = tmp_path / "driven.toml"
    driven.write_text("balls = 60\n[walls]\nleft = true\nright = true\nprecompression = 5.0\n"
                      "[drive]\nforce = 0.01\nfrequency = 5000.0\n[probes]\nbeads = [2, 30]\n"
                      "[stop]\nduration = 2e-3\n")
    for scene, cols in [(pushed, ["energy_dissipated", "shock_speed", "piston_work"]),
                        (driven, ["amplitude_2", "amplitude_30"])]:
        header, row = cli("run", str(scene), "--format", "csv").stdout.splitlines()
        want = dict(zip(header.split(","), row.split(",")))
        got = hc.run(str(scene))
        assert got["status"] == want["status"] == "ok"
        for c in cols:
            assert got[c] == float(want[c]) and got[c] > 0, c
    assert hc.run(str(pushed))["shock_speed"] > 300.0


def test_ctrl_c_stops_a_sweep_and_resume_finishes_it(tmp_path):
    spec = tmp_path / "big.toml"
    # 40,000 scenes: ~20 batches after the first 200 kB (the signal comes
    # within milliseconds of it), a few seconds in all (300,000 took 99 s of CI).
    spec.write_text(SMALL_TOML.replace("3]", "40]").replace("4]", "1000]"))
    out = tmp_path / "big.csv"
    script = textwrap.dedent(
        f"""\
        import sys, time, hertz_cradle as hc
        t = time.time()
        try:
            hc.sweep({str(spec)!r}, backend="cpu", out={str(out)!r}, progress=False)
        except KeyboardInterrupt:
            print("interrupted", time.time(), flush=True)
            sys.exit(3)
        print("finished", flush=True)
        """
    )
    p = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    partial = tmp_path / "big.csv.partial"
    t0 = time.time()
    while (not partial.exists() or partial.stat().st_size < 200_000) and time.time() - t0 < 60:
        time.sleep(0.01)
    sent = time.time()
    p.send_signal(signal.SIGINT)
    stdout, _ = p.communicate(timeout=30)
    assert p.returncode == 3, stdout
    stopped = float(stdout.split()[1])
    assert stopped - sent < 1.0, f"took {stopped - sent:.2f} s to stop"
    assert not out.exists() and partial.exists()
    # What was written is a prefix of the right answer; resume completes it.
    ref = tmp_path / "ref.csv"
    assert cli("sweep", spec, "--out", ref, "--backend", "cpu").returncode == 0
    assert ref.read_bytes().startswith(partial.read_bytes())
    hc.sweep(spec, backend="cpu", out=out, resume=True, progress=False)
    assert out.read_bytes() == ref.read_bytes()


def test_parquet_reads_back_the_csv_values_in_pandas_and_polars(tmp_path):
    pd = pytest.importorskip("pandas")
    pl = pytest.importorskip("polars")
    csv_path, pq_path = tmp_path / "t.csv", tmp_path / "t.parquet"
    assert cli("sweep", MASS_GAP, "--out", csv_path, "--backend", "cpu").returncode == 0
    assert cli("sweep", MASS_GAP, "--out", pq_path, "--backend", "cpu").returncode == 0
    a = pd.read_csv(csv_path)
    b = pd.read_parquet(pq_path)
    assert list(a.columns) == list(b.columns)
    for c in a.columns:
        x, y = a[c], b[c]
        if c == "status":
            assert (x == y.astype(str)).all()
        else:
            assert x.astype("float64").equals(y.astype("float64")), c
    p = pl.read_parquet(pq_path)
    assert p.shape == a.shape and p["ejected"].to_list() == a["ejected"].to_list()
    # Shards: read together as one dataset.
    for k in (1, 2):
        r = cli("sweep", MASS_GAP, "--out", tmp_path / f"s{k}.parquet", "--shard", f"{k}/2", "--backend", "cpu")
        assert r.returncode == 0, r.stderr
    both = pl.read_parquet([tmp_path / "s1.parquet", tmp_path / "s2.parquet"])
    assert both.equals(p)


def test_sobol_points_have_lower_discrepancy_than_random_ones():
    qmc = pytest.importorskip("scipy.stats.qmc")
    import numpy as np

    def unit_points(design):
        spec = {
            "scene": {"balls": 5, "velocity": [1.0, 0.0, 0.0, 0.0, 0.0]},
            "sample": {"design": design, "points": 1024, "seed": 0 if design == "sobol" else 11},
            "axis": [
                {"param": "mass[2]", "range": [0.0064, 0.64], "scale": "log"},
                {"param": "gap", "range": [0.0, 2e-5]},
            ],
        }
        t = hc.sweep(spec, backend="cpu", model="hard-sphere", progress=False)
        m = np.log(t.column("mass[2]").to_numpy() / 0.0064) / np.log(100.0)
        g = t.column("gap").to_numpy() / 2e-5
        return np.column_stack([m, g]).clip(0, 1)

    sob, rnd, lhs = unit_points("sobol"), unit_points("random"), unit_points("lhs")
    d_sob, d_rnd, d_lhs = (qmc.discrepancy(p) for p in (sob, rnd, lhs))
    assert d_sob < d_lhs and d_sob < d_rnd, (d_sob, d_lhs, d_rnd)
    # The same points as scipy's unscrambled Sobol sequence (Joe & Kuo).
    ref = qmc.Sobol(d=2, scramble=False).random(1024)
    assert np.allclose(sob, ref, atol=1e-9)


def test_optimize_writes_the_clis_bytes_and_its_best_scene_runs_again(tmp_path):
    problem = {
        "scene": {"balls": 3, "velocity": [1.0, 0, 0]},
        "variable": [{"name": "mass[1..2]", "min": 0.01, "max": 1.0, "scale": "log"}],
        "objective": {"maximize": "v_2"},
        "optimizer": {"population": 6, "evaluations": 36, "seed": 2},
    }
    table, best = hc.optimize(problem, backend="cpu", out=tmp_path / "py.csv")
    assert table.num_rows == 36
    assert table.column_names[:4] == ["generation", "candidate", "feasible", "mass[1]"]
    # The command line on the same problem (as TOML) writes the same bytes.
    toml = tmp_path / "p.toml"
    toml.write_text(
        '[scene]\nballs = 3\nvelocity = [1.0, 0, 0]\n'
        '[[variable]]\nname = "mass[1..2]"\nmin = 0.01\nmax = 1.0\nscale = "log"\n'
        '[objective]\nmaximize = "v_2"\n'
        '[optimizer]\npopulation = 6\nevaluations = 36\nseed = 2\n'
    )
    r = cli("optimize", toml, "--out", tmp_path / "cli.csv", "--backend", "cpu")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "py.csv").read_bytes() == (tmp_path / "cli.csv").read_bytes()
    # The best scene is the best feasible row, run again.
    rows = table.to_pylist()
    top = max(r["v_2"] for r in rows if r["feasible"] == "true")
    assert hc.run(best)["v_2"] == top
    with pytest.raises(ValueError, match="objective"):
        hc.optimize({**problem, "objective": {"maximize": "v_9"}}, backend="cpu")


def test_optimize_reports_each_generation_and_resumes_to_the_same_bytes(tmp_path):
    """`progress` is told each generation as it ends; an exception it
    raises stops the run between generations (as Ctrl-C does), the finished
    ones kept in out.partial; `resume=True` ends with the bytes of a run
    never stopped."""
    problem = {
        "scene": {"balls": 3, "velocity": [1.0, 0, 0]},
        "variable": [{"name": "mass[1..2]", "min": 0.01, "max": 1.0, "scale": "log"}],
        "objective": {"maximize": "v_2"},
        "optimizer": {"population": 6, "evaluations": 60, "seed": 5},
    }
    seen = []
    hc.optimize(problem, backend="cpu", out=tmp_path / "whole.csv",
                progress=lambda *a: seen.append(a))
    assert [s[0] for s in seen][-1] == 10 and all(s[1] == 10 for s in seen)
    assert seen[-1][2] == 60 and seen[-1][3] is not None
    assert json.loads((tmp_path / "whole.csv.json").read_text())["table"]["rows"] == 60

    class Stop(Exception):
        pass

    def stop_at_3(generation, generations, evaluations, best):
        if generation >= 3:
            raise Stop()

    cut = tmp_path / "cut.csv"
    with pytest.raises(Stop):
        hc.optimize(problem, backend="cpu", out=cut, progress=stop_at_3)
    partial = Path(str(cut) + ".partial")
    assert partial.exists() and not cut.exists()
    kept = len(partial.read_text().splitlines()) - 2
    assert kept % 6 == 0 and 18 <= kept < 60, kept
    hc.optimize(problem, backend="cpu", out=cut, resume=True, progress=False)
    assert cut.read_bytes() == (tmp_path / "whole.csv").read_bytes()
    assert not partial.exists()


def test_ctrl_c_stops_an_optimisation_between_generations(tmp_path):
    """SIGINT while an optimisation runs: KeyboardInterrupt, the finished
    generations kept whole in out.partial; resume finishes with the bytes
    of a run never stopped."""
    problem = tmp_path / "p.toml"
    problem.write_text(
        '[scene]\nballs = 3\nvelocity = [1.0, 0, 0]\n'
        '[[variable]]\nname = "mass[1..2]"\nmin = 0.01\nmax = 1.0\nscale = "log"\n'
        '[objective]\nmaximize = "v_2"\n'
        '[optimizer]\npopulation = 6\nevaluations = 600\nseed = 7\n'
    )
    out = tmp_path / "runs.csv"
    # Each generation waits a little in `progress` (told before the next
    # one starts): the signal comes after the first, mid-run.
    script = textwrap.dedent(
        f"""\
        import sys, time, hertz_cradle as hc
        def slow(g, *rest):
            print("generation", g, flush=True)
            time.sleep(0.05)
        try:
            hc.optimize({str(problem)!r}, backend="cpu", out={str(out)!r}, progress=slow)
        except KeyboardInterrupt:
            print("interrupted", flush=True)
            sys.exit(3)
        print("finished", flush=True)
        """
    )
    p = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().startswith("generation 1")
    p.send_signal(signal.SIGINT)
    rest = p.stdout.read()
    assert p.wait(timeout=60) == 3 and "interrupted" in rest, rest
    partial = Path(str(out) + ".partial")
    kept = len(partial.read_text().splitlines()) - 2
    assert kept % 6 == 0 and 6 <= kept < 600, kept
    assert not out.exists()
    hc.optimize(str(problem), backend="cpu", out=out, resume=True, progress=False)
    hc.optimize(str(problem), backend="cpu", out=tmp_path / "whole.csv", progress=False)
    assert out.read_bytes() == (tmp_path / "whole.csv").read_bytes()


def test_evaluate_runs_an_outside_optimisers_designs_as_optimize_would():
    """Ask/tell: designs asked by an optimiser of the user's own (here
    pycma's shape: a list of vectors, or dicts) run as one batch; each row is
    the row optimize writes for that design."""
    problem = {
        "scene": {"balls": 3, "velocity": [1.0, 0, 0]},
        "variable": [{"name": "mass[1..2]", "min": 0.01, "max": 1.0, "scale": "log"}],
        "objective": {"maximize": "v_2"},
        "constraint": [{"expr": "total_mass <= 0.5"}],
    }
    designs = [[0.05, 0.05], [0.3, 0.02], [0.4, 0.4]]
    t = hc.evaluate(problem, designs, backend="cpu")
    assert t.num_rows == 3
    rows = t.to_pylist()
    assert [r["mass[1]"] for r in rows] == [0.05, 0.3, 0.4]
    assert [r["feasible"] for r in rows] == ["true", "true", "false"]
    assert all(r["status"] == "ok" and r["v_2"] > 0 for r in rows)
    # Dicts by variable name give the same rows; an unknown name or a value
    # outside its range is refused, naming it.
    by_name = hc.evaluate(problem, [{"mass[1]": a, "mass[2]": b} for a, b in designs], backend="cpu")
    assert by_name.equals(t)
    with pytest.raises(ValueError, match="unknown: mass.3."):
        hc.evaluate(problem, [{"mass[1]": 0.1, "mass[2]": 0.1, "mass[3]": 0.1}], backend="cpu")
    with pytest.raises(ValueError, match=r"design 1: mass\[2\] = 2: allowed 0.01 to 1"):
        hc.evaluate(problem, [[0.1, 0.1], [0.1, 2.0]], backend="cpu")
    # An optimisation's designs evaluated again: the same rows, cell for cell.
    table, _ = hc.optimize(
        {**problem, "optimizer": {"population": 4, "evaluations": 8, "seed": 3}}, backend="cpu"
    )
    opt = table.to_pylist()
    again = hc.evaluate(problem, [[r["mass[1]"], r["mass[2]"]] for r in opt], backend="cpu")
    for a, b in zip(opt, again.to_pylist()):
        for c in a:
            if c not in ("generation", "candidate"):
                assert a[c] == b[c] or (a[c] != a[c] and b[c] != b[c]), (c, a[c], b[c])
