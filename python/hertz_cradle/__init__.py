"""Newton's cradles with Hertzian contacts, swept from Python.

The engine of the ``cradle`` command line tool (Rust; GPU through wgpu, or
every CPU core), as a module::

    import hertz_cradle as hc
    table = hc.sweep("examples/mass_gap.toml")      # a pyarrow.Table
    df = table.to_pandas()                          # or polars.from_arrow(table)
    outcome = hc.run("cradle-1")                    # one scene: a dict

Every function checks its input exactly as ``cradle`` does and raises
``ValueError`` with the message ``cradle`` prints (file, line, key, allowed
range). Scenes run with the GIL released; Ctrl-C stops a sweep within a
fraction of a second (``KeyboardInterrupt``), and a sweep written to a file
(``out=``) is then left as ``FILE.partial``, which ``resume=True`` finishes.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import pyarrow as pa
import pyarrow.csv as pcsv
import pyarrow.parquet as pq

from . import _native

__all__ = ["sweep", "run", "optimize", "evaluate", "scenes", "__version__"]
__version__: str = _native.__version__

Spec = Union[str, "os.PathLike[str]", Mapping[str, Any]]

_TYPES = {
    "int64": pa.int64(),
    "float64": pa.float64(),
    "string": pa.string(),
    "dictionary": pa.string(),  # read as text, then dictionary-encoded
}


def _document(spec: Spec, what: str) -> Tuple[Optional[str], Optional[str], bool, str]:
    """(path, text, text_is_json, name) for a path, TOML text or a dict."""
    if isinstance(spec, Mapping):
        return None, json.dumps(spec, allow_nan=False), True, f"<{what} dict>"
    if isinstance(spec, os.PathLike):
        return os.fspath(spec), None, False, os.fspath(spec)
    if isinstance(spec, str):
        # A path: an existing file, or a name ending in .toml (a folder may
        # hold a `=`: runs/v=0.1/sweep.toml). TOML text: a newline or a `=`
        # in anything else. A built-in scene name has neither.
        if os.path.isfile(spec) or (spec.endswith(".toml") and "\n" not in spec):
            return spec, None, False, spec
        if "\n" in spec or "=" in spec:
            return None, spec, False, f"<{what} string>"
        return spec, None, False, spec
    raise TypeError(f"{what} must be a path, a TOML string or a dict, not {type(spec).__name__}")


def _read_table(path: str, columns: List[Tuple[str, str]]) -> pa.Table:
    """A sweep's output file as a Table with the Parquet output's types."""
    with open(path, "rb") as f:
        magic = f.read(4)
    if magic == b"PAR1":
        return pq.read_table(path, memory_map=False)
    names = [n for n, _ in columns]
    types = {n: _TYPES[t] for n, t in columns}
    table = pcsv.read_csv(
        path,
        convert_options=pcsv.ConvertOptions(
            column_types=types, strings_can_be_null=True, quoted_strings_can_be_null=False
        ),
    )
    if table.column_names != names:
        raise RuntimeError(f"{path}: columns {table.column_names}, expected {names}")
    for i, (n, t) in enumerate(columns):
        if t == "dictionary":
            table = table.set_column(i, n, table.column(i).dictionary_encode())
    # The Parquet output's schema: id and status are never missing.
    fields = [
        pa.field(n, table.schema.field(n).type, nullable=n != "id" and t != "dictionary")
        for n, t in columns
    ]
    return table.cast(pa.schema(fields))


def _seen(stream) -> bool:
    """Whether a person sees `stream`: a terminal, or a Jupyter notebook's
    output."""
    try:
        return stream.isatty() or "ipykernel" in sys.modules
    except (AttributeError, ValueError):
        return False


def _bar(stream=None):
    """The default progress: a bar redrawn on one line of stderr, where a
    person sees it, else None."""
    stream = stream or sys.stderr
    if not _seen(stream):
        return None
    start = time.monotonic()

    def draw(done: int, total: int) -> None:
        filled = int(40 * done / total) if total else 0
        rate = done / max(time.monotonic() - start, 1e-9)
        line = f"{'#' * filled}{'.' * (40 - filled)} {done}/{total} scenes  {rate:.0f} scenes/s"
        end = "\n" if done >= total else ""
        stream.write("\r" + line + end)
        stream.flush()

    return draw


def _generations(stream=None):
    """The default progress of an optimisation: a line per generation on
    stderr, where a person sees it, else None."""
    stream = stream or sys.stderr
    if not _seen(stream):
        return None

    def line(generation: int, generations: int, evaluations: int, best: Optional[float]) -> None:
        said = "none feasible yet" if best is None else f"{best:.6g}"
        stream.write(f"generation {generation}/{generations}: {evaluations} evaluations, best {said}\n")
        stream.flush()

    return line


def sweep(
    spec: Spec,
    *,
    backend: str = "auto",
    precision: Optional[str] = None,
    tolerance: Optional[float] = None,
    method: Optional[str] = None,
    model: Optional[str] = None,
    threads: Optional[int] = None,
    progress: Union[bool, Callable[[int, int], Any]] = True,
    out: Optional[Union[str, "os.PathLike[str]"]] = None,
    format: Optional[str] = None,
    resume: bool = False,
    shard: Optional[str] = None,
    error_estimate: bool = False,
) -> pa.Table:
    """Run every scene of a sweep; return the outcome table.

    ``spec`` is a sweep TOML file's path, TOML text, or a dict with the
    TOML's structure (``{"scene": {...}, "axis": [{"param": "gap",
    "linspace": [0, 2e-5, 100]}]}``); a relative ``scene = "file.toml"`` in
    text or a dict is found from the current directory. The other arguments
    are ``cradle sweep``'s flags: ``backend`` ("auto", "gpu", "cpu"),
    ``precision`` ("f32", "f64", "df64"), ``tolerance``, ``method``, ``model``
    ("hertz", "hard-sphere", "closure"), ``threads``, ``shard`` ("K/N"),
    ``error_estimate``.

    ``progress``: ``True`` draws a bar on stderr where someone sees it (a
    terminal, or a Jupyter notebook: one line, redrawn); a callable is
    called as ``progress(done, total)`` (scenes written, scenes in all) as
    the count moves, at most every 50 ms and once at the end, e.g. to feed
    ``tqdm``; an exception it raises stops the sweep; ``False``: nothing.

    The table has exactly the CSV's columns and values (``id``, one column
    per axis, ``status``, ``v_0`` ...), typed as in the Parquet output:
    integers as int64, ``status`` dictionary-encoded, missing values null.

    ``out`` also writes the table to that file (CSV for a name ending in
    ``.csv``, Parquet for ``.parquet`` or ``.pq``; another name needs
    ``format``, which must agree with a known extension), with its JSON sidecar, as
    the command line does; ``resume=True`` continues an interrupted run into
    it. Without ``out`` nothing is left on disk.
    """
    path, text, is_json, name = _document(spec, "sweep")
    with tempfile.TemporaryDirectory(prefix="hertz_cradle_") as tmp:
        target = os.fspath(out) if out is not None else os.path.join(tmp, "sweep.parquet")
        summary = _native.sweep(
            path,
            text,
            is_json,
            name,
            os.getcwd(),
            target,
            backend=backend,
            precision=precision,
            tolerance=None if tolerance is None else float(tolerance),
            method=method,
            model=model,
            threads=None if threads is None else int(threads),
            format=None if format is None else str(format),
            resume=bool(resume),
            shard=None if shard is None else str(shard),
            error_estimate=bool(error_estimate),
            progress=progress if callable(progress) else (_bar() if progress else None),
        )
        return _read_table(target, summary["columns"])


def run(
    scene: Spec,
    *,
    trace_dt: Optional[float] = None,
    trace: bool = False,
    model: str = "hertz",
    precision: Optional[str] = None,
    tolerance: Optional[float] = None,
    method: Optional[str] = None,
) -> Union[Dict[str, Any], Tuple[Dict[str, Any], pa.Table]]:
    """Run one scene; return its outcome (a dict of the sweep row's columns).

    ``scene`` is a built-in scene's name (see :func:`scenes`), a scene TOML
    file's path, TOML text, or a dict with the TOML's structure. With
    ``trace_dt`` (seconds of simulated time between rows) or ``trace=True``
    (the command line's default spacing), returns ``(outcome, trace)``:
    the trajectory (``t``, ``x_0`` ..., ``v_0`` ...; SI units) as a Table.
    """
    path, text, is_json, name = _document(scene, "scene")
    want_trace = trace or trace_dt is not None
    with tempfile.TemporaryDirectory(prefix="hertz_cradle_") as tmp:
        trace_path = os.path.join(tmp, "trace.csv") if want_trace else None
        outcome = _native.run(
            path,
            text,
            is_json,
            name,
            precision=precision,
            tolerance=None if tolerance is None else float(tolerance),
            method=method,
            model=model,
            trace=trace_path,
            trace_dt=None if trace_dt is None else float(trace_dt),
        )
        if not want_trace:
            return outcome
        return outcome, pcsv.read_csv(trace_path)


def optimize(
    spec: Spec,
    *,
    backend: str = "auto",
    precision: Optional[str] = None,
    tolerance: Optional[float] = None,
    method: Optional[str] = None,
    model: Optional[str] = None,
    threads: Optional[int] = None,
    out: Optional[Union[str, "os.PathLike[str]"]] = None,
    best: Optional[Union[str, "os.PathLike[str]"]] = None,
    resume: bool = False,
    progress: Union[bool, Callable[[int, int, int, Optional[float]], Any]] = True,
) -> Tuple[pa.Table, Optional[str]]:
    """Search for the best design (``cradle optimize``, docs/SPEC.md §10).

    ``spec`` is a problem TOML file's path, TOML text, or a dict with the
    TOML's structure (``{"scene": {...}, "variable": [{"name":
    "radius[1..20]", "min": 0.002, "max": 0.008, "scale": "log"}],
    "objective": {"minimize": "wall_right_peak_force"}, "optimizer":
    {"evaluations": 1000, "seed": 1}}``). The other arguments are
    ``cradle optimize``'s flags.

    Returns ``(table, best_scene)``: every evaluation (``generation``,
    ``candidate``, ``feasible``, each variable, ``total_mass``, the model's
    outcome columns) typed as a sweep's table, and the best feasible design
    as scene TOML text (``None`` if no candidate was feasible), which
    :func:`run` and ``cradle run`` reproduce bit for bit. ``out`` and
    ``best`` also write them to files (``out``: CSV or Parquet by the name,
    with its JSON sidecar, as the command line does).

    ``progress``: ``True`` prints a line per generation on stderr where
    someone sees it (a terminal, a Jupyter notebook), as the command line
    does; a callable is called as ``progress(generation, generations,
    evaluations, best)`` (``best``: the best feasible objective so far, or
    ``None``) as each generation ends; an exception it raises stops the
    run; ``False``: nothing.

    Ctrl-C (``KeyboardInterrupt``) stops the run between generations; with
    ``out``, the finished generations are kept in ``out + ".partial"`` and
    ``resume=True`` continues them to the table an uninterrupted run
    writes (the same bytes).
    """
    path, text, is_json, name = _document(spec, "problem")
    with tempfile.TemporaryDirectory(prefix="hertz_cradle_") as tmp:
        target = os.fspath(out) if out is not None else os.path.join(tmp, "runs.parquet")
        summary = _native.optimize(
            path,
            text,
            is_json,
            name,
            os.getcwd(),
            target,
            best=None if best is None else os.fspath(best),
            backend=backend,
            precision=precision,
            tolerance=None if tolerance is None else float(tolerance),
            method=method,
            model=model,
            threads=None if threads is None else int(threads),
            resume=bool(resume),
            progress=progress if callable(progress) else (_generations() if progress else None),
        )
        return _read_table(target, summary["columns"]), summary["best_scene"]


def evaluate(
    spec: Spec,
    designs: Sequence[Union[Sequence[Union[float, str]], Mapping[str, Union[float, str]]]],
    *,
    backend: str = "auto",
    precision: Optional[str] = None,
    tolerance: Optional[float] = None,
    method: Optional[str] = None,
    model: Optional[str] = None,
    threads: Optional[int] = None,
) -> pa.Table:
    """Run designs of an optimisation problem as one batch: the engine's
    evaluation for an optimiser of your own (ask/tell with pycma, Optuna,
    nevergrad: they ask for designs, these rows tell them the objective).

    ``spec`` is a problem as :func:`optimize` takes it; ``designs`` a list
    of designs, each a mapping from variable name (``"radius[3]"``) to its
    value or a sequence of the values in the problem's variable order (the
    table's columns after ``feasible``). Values are the variables' own
    (metres, pascals, a choice), inside their ranges or among their choices
    (outside: ``ValueError`` naming the design, the variable and what it
    allows).

    Returns a table with one row per design, in order, as ``cradle
    optimize`` writes a generation (``generation`` 0, ``candidate`` k,
    ``feasible``, each variable, ``total_mass``, the model's outcome
    columns, ``status``: a row that misses its tolerance says so).
    """
    path, text, is_json, name = _document(spec, "problem")

    def plain(v: Union[float, str]) -> Union[float, str]:
        return v if isinstance(v, str) else float(v)  # numpy floats too

    # Mappings stay mappings: the module puts them in the variables' order.
    rows = [
        {str(k): plain(v) for k, v in d.items()} if isinstance(d, Mapping) else [plain(v) for v in d]
        for d in designs
    ]
    with tempfile.TemporaryDirectory(prefix="hertz_cradle_") as tmp:
        target = os.path.join(tmp, "designs.parquet")
        columns = _native.evaluate(
            path,
            text,
            is_json,
            name,
            os.getcwd(),
            target,
            json.dumps(rows),
            backend=backend,
            precision=precision,
            tolerance=None if tolerance is None else float(tolerance),
            method=method,
            model=model,
            threads=None if threads is None else int(threads),
        )
        return _read_table(target, columns)


def scenes() -> Dict[str, str]:
    """The built-in scenes: name → one-line summary."""
    return dict(_native.scenes())
