"""docs/analysis.md names the report files that each ``spikesim analyze`` study writes."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
_STEM = re.compile(r'Result\(\s*"(\w+)"')


def test_the_intro_names_every_report_stem():
    intro = (ROOT / "docs" / "analysis.md").read_text(encoding="utf-8").split("\n\n")[1]
    stems = {s for p in sorted((ROOT / "spikesim" / "analysis").glob("*.py"))
             for s in _STEM.findall(p.read_text(encoding="utf-8"))}
    assert {"transfer", "calibration", "calibration_short"} <= stems
    for stem in stems:
        assert f"`{stem}`" in intro or f"`{stem}.md`" in intro, stem
    assert "`sensor.json`" in intro
