"""Every fenced code block of README.md and docs/ runs, so an example never
fails for the user who copies it first.

Conventions of the Markdown files (kept invisible to readers):

* ```` ```python ```` blocks of one file run in order, in one shared namespace,
  in a fresh temporary working directory (one per file);
* ```` ```bash ```` (or ``sh``/``shell``/``console``) blocks run as one bash
  script (``set -euo pipefail``) in that directory, with this interpreter's
  ``spikesim``/``spikejdd`` first on ``PATH``; a leading ``$ `` prompt is
  dropped;
* ``<!-- doc-setup ... -->`` right before a block holds Python run first, in
  the same namespace and directory (to make a small input the example names;
  the makers in ``tests/support/doc_fixtures.py``, e.g. ``make_reds()``, are in scope);
* ``<!-- doc-file: NAME -->`` right before a block of any language writes the
  block to ``NAME`` in the directory instead of running it (a manifest, a
  config) so that later blocks can use it;
* ``<!-- not-run: reason -->`` right before a block skips it; the reason is
  required (commands meant for other hosts, or for the whole test run itself).

A Python block may not warn (a warning of spikesim's or spikejdd's, or one
raised by the example's own lines): a reader would see it under the example.

Blocks in other languages (``toml``, ``text``, none) are prose and not run,
unless a ``doc-file`` comment names them.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
import warnings
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.support import doc_fixtures

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
RUN_PYTHON = {"python", "py", "pycon"}
RUN_SHELL = {"bash", "sh", "shell", "console"}

_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})(?P<info>[^`]*)$")
_COMMENT = re.compile(r"<!--\s*(?P<kind>doc-setup|doc-file:|not-run:)(?P<body>.*?)-->", re.DOTALL)


@dataclass
class Block:
    """One fenced block: its language, text, first line and directive."""

    lang: str
    code: str
    line: int
    directive: str | None = None   # "doc-setup", "doc-file:", "not-run:" or None
    argument: str = ""             # the setup code, file name or reason


def parse_blocks(text: str) -> list[Block]:
    """The fenced blocks of a Markdown text with the directive comment that
    stands right before each (only blank lines between)."""
    lines = text.splitlines()
    blocks: list[Block] = []
    i = 0
    pending: tuple[str, str, int] | None = None   # directive, argument, line after it
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            stripped = lines[i].strip()
            if stripped.startswith("<!--"):
                j = i
                chunk = lines[i]
                while "-->" not in chunk and j + 1 < len(lines):
                    j += 1
                    chunk += "\n" + lines[j]
                c = _COMMENT.search(chunk)
                if c:
                    pending = (c["kind"], c["body"], j + 1)
                i = j + 1
                continue
            if stripped and pending is not None:
                pending = None   # prose between the comment and a block: not its block
            i += 1
            continue
        fence, indent = m["fence"], len(m["indent"])
        lang = (m["info"].strip().split() or [""])[0].lower()
        start = i + 1
        i += 1
        body = []
        while i < len(lines) and not lines[i].strip().startswith(fence):
            body.append(lines[i][indent:] if lines[i][:indent].strip() == "" else lines[i])
            i += 1
        i += 1
        block = Block(lang, "\n".join(body) + "\n", start + 1)
        if pending is not None and pending[2] <= start:
            block.directive, block.argument = pending[0], pending[1]
        pending = None
        blocks.append(block)
    return blocks


def _shell_env() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    env.setdefault("MPLBACKEND", "Agg")
    return env


def _is_ours(caught: warnings.WarningMessage, rel: Path) -> bool:
    """A warning that spikesim or spikejdd gives (a reader would see it under
    the example): its class is theirs, or it comes from their code or the
    example's own lines (``rel``); third-party deprecations are left alone."""
    module = caught.category.__module__.split(".")[0]
    parents = Path(caught.filename).resolve().parents
    return (module in ("spikesim", "spikejdd") or caught.filename.startswith(str(rel))
            or ROOT / "spikesim" in parents or ROOT / "spikejdd" in parents)


def run_file(doc: Path, workdir: Path) -> int:
    """Run every block of ``doc`` in ``workdir``; returns how many ran."""
    namespace: dict = {"__name__": "__doc_example__", **doc_fixtures.NAMES}
    ran = 0
    rel = doc.relative_to(ROOT) if ROOT in doc.parents else Path(doc.name)
    for block in parse_blocks(doc.read_text(encoding="utf-8")):
        where = f"{rel}:{block.line}"
        if block.directive == "not-run:":
            assert block.argument.strip(), f"{where}: not-run needs a reason"
            continue
        if block.directive == "doc-file:":
            (workdir / block.argument.strip()).write_text(block.code, encoding="utf-8")
            continue
        if block.lang not in RUN_PYTHON | RUN_SHELL:
            continue
        if block.directive == "doc-setup":
            exec(compile(textwrap.dedent(block.argument), f"{where} (setup)", "exec"), namespace)
        if block.lang in RUN_PYTHON:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                exec(compile(block.code, where, "exec"), namespace)
            ours = [w for w in caught if _is_ours(w, rel)]
            assert not ours, f"{where}: the example warns: " + "; ".join(
                f"{w.category.__name__}: {w.message}" for w in ours)
        else:
            script = "\n".join(re.sub(r"^\$ ", "", ln) for ln in block.code.splitlines())
            proc = subprocess.run(["bash", "-c", "set -euo pipefail\n" + script], cwd=workdir,
                                  env=_shell_env(), capture_output=True, text=True)
            assert proc.returncode == 0, (
                f"{where}: the shell block exited {proc.returncode}\n--- block\n{block.code}"
                f"--- stdout\n{proc.stdout[-3000:]}\n--- stderr\n{proc.stderr[-3000:]}")
        ran += 1
    return ran


@pytest.mark.timeout(900)
@pytest.mark.parametrize("doc", DOCS, ids=[str(d.relative_to(ROOT)) for d in DOCS])
def test_every_code_block_runs(doc, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name, value in _shell_env().items():   # python blocks may start the commands too
        monkeypatch.setenv(name, value)
    run_file(doc, tmp_path)


def test_the_parser_sees_directives_indents_and_prose_between():
    text = textwrap.dedent("""\
        <!-- not-run: elsewhere -->
        ```bash
        dask scheduler
        ```
        <!-- doc-setup
        x = 1
        -->

        ```python
        print(x)
        ```
        <!-- doc-file: a.toml -->
        ```toml
        k = 1
        ```
        <!-- not-run: stale -->
        Some prose.
        ```python
        y = 2
        ```
        1. A list item:
           ```bash
           echo hi
           ```
        """)
    blocks = parse_blocks(text)
    assert [(b.lang, b.directive) for b in blocks] == [
        ("bash", "not-run:"), ("python", "doc-setup"), ("toml", "doc-file:"),
        ("python", None), ("bash", None)]
    assert blocks[1].argument.strip() == "x = 1"
    assert blocks[2].argument.strip() == "a.toml"
    assert blocks[4].code == "echo hi\n"
    assert blocks[0].line == 3


def test_an_example_that_warns_fails(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    doc = tmp_path / "warns.md"
    doc.write_text("```python\nimport warnings\nx = 1\n```\n\n"
                   "```python\nwarnings.warn('the video ends')\n```\n", encoding="utf-8")
    with pytest.raises(AssertionError,
                       match=r"warns.md:7: the example warns: UserWarning: the video ends"):
        run_file(doc, tmp_path)
