"""The simulation half of the main job: build a small dataset from built-in scenes
and preview it.

``build_demo`` builds the built-in ``demo`` manifest (8 procedural sequences,
256×256 RGGB at 20 kHz, Gaussian and Poisson–Gaussian paper-mode noise, three
39-readout windows each) with the dataset builder and writes a TFP preview of
every sequence next to its ground truth; ``demo_report`` turns its result into
Markdown.  ``spikejdd.demo.run_demo`` (``spikejdd demo``, ``make demo``) adds
the reconstruction half: classical pipelines and SJDD-Net, scored and timed.
"""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager, nullcontext
from pathlib import Path

import numpy as np

from spikesim.errors import bad_value
from spikesim.srgb import linear_to_srgb8

__all__ = ["Stages", "build_demo", "demo_report", "preview_report"]


class Stages:
    """Say each stage of a long job as it starts and as it ends, with the seconds it
    took: ``LABEL: [2/4] WHAT ...`` then ``LABEL: [2/4] WHAT: done in 12.3 s``, one
    flushed line each on ``stream`` (default stderr, where the progress bars go),
    terminal or not; a stage cut short by an error says after how long.

    >>> import io
    >>> out = io.StringIO()
    >>> stages = Stages("demo", 1, stream=out)
    >>> with stages("resting"):
    ...     pass
    >>> print(out.getvalue().replace("0.0", "T"), end="")
    demo: [1/1] resting ...
    demo: [1/1] resting: done in T s
    """

    def __init__(self, label: str, total: int, stream=None):
        self.label, self.total, self.stream = label, total, stream
        self.count = 0

    def say(self, text: str) -> None:
        print(f"{self.label}: {text}", file=self.stream or sys.stderr, flush=True)

    @contextmanager
    def __call__(self, what: str):
        self.count += 1
        tag = f"[{self.count}/{self.total}] {what}"
        self.say(f"{tag} ...")
        t0 = time.perf_counter()
        try:
            yield
        except BaseException:
            self.say(f"{tag}: stopped after {time.perf_counter() - t0:.1f} s")
            raise
        self.say(f"{tag}: done in {time.perf_counter() - t0:.1f} s")


def _demo_manifest(size: int | None):
    import tomllib

    from spikesim.dataset.manifest import builtin_manifest_path, parse_manifest

    data = tomllib.loads(builtin_manifest_path("demo").read_text())
    if size is not None:
        if isinstance(size, bool) or not isinstance(size, int) or size < 16:
            raise bad_value("size", size, "an integer >= 16 pixels")
        data["dataset"]["size"] = [size, size]
    return parse_manifest(data, origin="builtin:demo")


def build_demo(out_dir: str | Path = "demo_out", size: int | None = None,
               limit: int | None = None, progress: bool = True,
               stages: Stages | None = None) -> dict:
    """Build the demo dataset into ``<out_dir>/demo`` and a preview PNG per sequence.

    Returns ``{"size", "window", "data_dir", "sequences", "build_seconds", "built",
    "reused"}``; a sequence that fails raises ``RuntimeError`` naming it.  With
    ``stages`` (:class:`Stages`) the two stages, simulating and previewing, are said
    as they start and end.
    """
    from spikesim.dataset import build_dataset

    out = Path(out_dir)
    manifest = _demo_manifest(size)
    stage = stages or (lambda what: nullcontext())
    h, w = manifest.size
    t0 = time.perf_counter()
    with stage(f"simulating the demo data set ({h}x{w}"
               f"{'' if limit is None else f', the first {limit} sequences'}) into {out}"):
        summary = build_dataset(manifest, out, workers=1, progress=progress, limit=limit)
        if summary.failed:
            raise RuntimeError("demo sequences failed: " + "; ".join(
                f"{r['file']}: {r['error']}" for r in summary.failures))
    build_s = time.perf_counter() - t0
    with stage("previewing each sequence (TFP over 39 readouts)"):
        sequences = _previews(out, summary)
    return {"size": list(manifest.size), "window": manifest.window,
            "data_dir": str(out / "demo"), "sequences": sequences, "build_seconds": build_s,
            "built": summary.done, "reused": summary.skipped}


def _previews(out: Path, summary) -> list[dict]:
    """A preview PNG and the table row of every sequence of the built data set."""
    from spikesim.io import open_dataset
    from spikesim.io.preview import estimate_image, save_image

    data_dir = out / "demo"
    ds = open_dataset(data_dir)
    records = {r["id"]: r for r in summary.records}
    sequences = []
    for name in ds.names:
        seq = ds.sequence(name)
        g = int(seq.gt_index[0])
        est = estimate_image(seq, g, "tfp", window=39)
        gt = seq.read_gt(0)
        preview = out / f"{name}_preview.png"
        save_image(preview, [np.concatenate([linear_to_srgb8(est), linear_to_srgb8(gt)],
                                            axis=1)])
        counts = seq.read_window(0, seq.n_readouts).mean(dtype=np.float64)
        noise = (seq.meta.get("sensor") or {}).get("noise") or {}
        rec = records.get(name, {})
        sequences.append({
            "name": name, "noise": seq.meta.get("dataset", {}).get("noise_label", ""),
            "sigma_g": noise.get("sigma_g", 0.0), "sigma_p": noise.get("sigma_p", 0.0),
            "readouts": seq.n_readouts, "firing_rate": float(counts),
            "bytes": (data_dir / f"{name}.h5").stat().st_size,
            "sim_seconds": rec.get("seconds", {}).get("total"),
            "preview": preview.name,
        })
        seq.close()
    return sequences


def demo_report(r: dict, title: str = "spikesim demo") -> list[str]:
    """Markdown lines of :func:`build_demo`'s result: the sequence table."""
    h, w = r["size"]
    lines = [
        f"# {title}",
        "",
        f"{len(r['sequences'])} sequences ({h}×{w} RGGB, 20 kHz, three 39-readout windows "
        f"each, paper-mode noise) from the dataset builder (`spikesim dataset builtin:demo`): "
        f"{r['built']} simulated in {r['build_seconds']:.1f} s, {r['reused']} reused from an "
        "earlier run.",
        "",
        "| sequence | noise | σ_g (DN) | σ_p | readouts | mean firing rate | file (KiB) |"
        " simulate+write (s) |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for s in r["sequences"]:
        sec = s["sim_seconds"]
        lines.append(f"| {s['name']} | {s['noise']} | {s['sigma_g']:.1f} | {s['sigma_p']:.1f} | "
                     f"{s['readouts']} | {s['firing_rate']:.3f} | {s['bytes'] / 1024:.0f} | "
                     f"{'—' if sec is None else f'{sec:.2f}'} |")
    return lines


def preview_report(r: dict) -> list[str]:
    """Markdown lines showing every sequence's preview PNG."""
    lines = ["", "## Previews (TFP over 39 readouts, Malvar 2004, sRGB | ground truth)", ""]
    for s in r["sequences"]:
        lines.append(f"**{s['name']}** ({s['noise']})\n\n![{s['name']}]({s['preview']})\n")
    return lines
