"""Type stubs of the Rust extension (python/src/lib.rs), a client of the
core's typed API. Use the functions of ``hertz_cradle`` itself."""

from typing import Callable, Any, Dict, List, Optional, Tuple

__version__: str

def sweep(
    path: Optional[str],
    text: Optional[str],
    json: bool,
    name: str,
    base_dir: str,
    out: str,
    *,
    backend: str = "auto",
    precision: Optional[str] = None,
    tolerance: Optional[float] = None,
    method: Optional[str] = None,
    model: Optional[str] = None,
    threads: Optional[int] = None,
    format: Optional[str] = None,
    resume: bool = False,
    shard: Optional[str] = None,
    error_estimate: bool = False,
    progress: Optional[Callable[[int, int], Any]] = None,
) -> Dict[str, Any]:
    """Run a sweep into ``out``; a summary with ``columns`` [(name, type)]."""

def run(
    scene: Optional[str],
    text: Optional[str],
    json: bool,
    name: str,
    *,
    precision: Optional[str] = None,
    tolerance: Optional[float] = None,
    method: Optional[str] = None,
    model: Optional[str] = None,
    trace: Optional[str] = None,
    trace_dt: Optional[float] = None,
) -> Dict[str, Any]:
    """Run one scene; the outcome row as a dict."""

def optimize(
    path: Optional[str],
    text: Optional[str],
    json: bool,
    name: str,
    base_dir: str,
    out: str,
    *,
    best: Optional[str] = None,
    backend: str = "auto",
    precision: Optional[str] = None,
    tolerance: Optional[float] = None,
    method: Optional[str] = None,
    model: Optional[str] = None,
    threads: Optional[int] = None,
    resume: bool = False,
    progress: Optional[Callable[[int, int, int, Optional[float]], Any]] = None,
) -> Dict[str, Any]:
    """Run an optimisation into ``out``; a summary with ``columns`` and ``best_scene``."""

def evaluate(
    path: Optional[str],
    text: Optional[str],
    json: bool,
    name: str,
    base_dir: str,
    out: str,
    designs: str,
    *,
    backend: str = "auto",
    precision: Optional[str] = None,
    tolerance: Optional[float] = None,
    method: Optional[str] = None,
    model: Optional[str] = None,
    threads: Optional[int] = None,
) -> List[Tuple[str, str]]:
    """Run ``designs`` (JSON: per design a mapping by variable name or the values in order) as one batch into ``out``; the table's columns."""

def scenes() -> List[Tuple[str, str]]:
    """The built-in scenes: (name, summary)."""
