"""Report output shared by every study: JSON figures, Markdown tables, PNG plots.

Each study returns an :class:`AnalysisResult`: JSON-able ``data`` (the numbers),
Markdown ``tables`` and ``notes``, and a ``plot`` callable drawing the figure
on a matplotlib ``Figure``.  :func:`write_report` writes ``<name>.json``,
``<name>.md`` and ``<name>.png`` into a folder (matplotlib is imported only
there, with the non-interactive Agg backend).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from spikesim.errors import SpikeSimFileError

__all__ = ["AnalysisResult", "write_report", "markdown_table", "jsonable"]


@dataclass
class AnalysisResult:
    """The outcome of one study (see module docstring)."""

    name: str
    title: str
    data: dict
    tables: list = field(default_factory=list)  # (caption, headers, rows)
    notes: list = field(default_factory=list)
    plot: Callable | None = None

    def to_dict(self) -> dict:
        return jsonable({"name": self.name, "title": self.title, **self.data})

    def markdown(self, image: str | None = None) -> str:
        lines = [f"# {self.title}", ""]
        for note in self.notes:
            lines += [note, ""]
        if image:
            lines += [f"![{self.title}]({image})", ""]
        for caption, headers, rows in self.tables:
            lines += [f"**{caption}**", "", markdown_table(headers, rows), ""]
        return "\n".join(lines)


def jsonable(obj):
    """Convert numpy scalars/arrays (and non-finite floats → None) for ``json.dumps``."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    return obj


def _fmt(v) -> str:
    if isinstance(v, str):
        return v
    if v is None:
        return "–"
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    v = float(v)
    if not math.isfinite(v):
        return "∞" if v > 0 else ("−∞" if v < 0 else "–")
    if v == 0:
        return "0"
    if abs(v) >= 1e4 or abs(v) < 1e-3:
        return f"{v:.3e}"
    return f"{v:.4g}"


def markdown_table(headers, rows) -> str:
    """A GitHub-flavoured Markdown table; floats with 4 significant digits."""
    out = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    out += ["| " + " | ".join(_fmt(v) for v in row) + " |" for row in rows]
    return "\n".join(out)


def write_report(result: AnalysisResult, out_dir: str | os.PathLike, dpi: int = 80,
                 name: str | None = None) -> dict[str, Path]:
    """Write ``<name>.json``, ``<name>.md`` and (when the result has a plot) ``<name>.png``.

    ``name`` defaults to ``result.name``.
    """
    out = Path(out_dir)
    stem = name or result.name
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SpikeSimFileError(f"cannot create report folder {str(out)!r}: {exc}") from exc
    paths = {"json": out / f"{stem}.json", "md": out / f"{stem}.md"}
    image = None
    if result.plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        from matplotlib.figure import Figure

        fig = Figure(figsize=(9, 3.6), layout="constrained")
        result.plot(fig)
        paths["png"] = out / f"{stem}.png"
        fig.savefig(paths["png"], dpi=dpi)
        image = paths["png"].name
    paths["json"].write_text(json.dumps(result.to_dict(), indent=1) + "\n")
    paths["md"].write_text(result.markdown(image))
    return paths
