"""Type stubs of the Rust extension (python/src/lib.rs). Use the functions of
``hertz_cradle`` itself; these take the command line's argument lists."""

from typing import Any, Dict, List, Optional, Tuple

__version__: str

def sweep(
    args: List[str],
    text: Optional[str] = None,
    json: bool = False,
    name: str = "<string>",
    base_dir: str = ".",
    progress: bool = True,
) -> Dict[str, Any]:
    """Run ``cradle sweep ARGS``; a summary with ``columns`` [(name, type)]."""

def run(
    args: List[str],
    text: Optional[str] = None,
    json: bool = False,
    name: str = "<string>",
) -> Dict[str, Any]:
    """Run ``cradle run ARGS``; the outcome row as a dict."""

def scenes() -> List[Tuple[str, str]]:
    """The built-in scenes: (name, summary)."""
