"""``spikesim scenes`` lists scenes, motions and flow methods."""

from __future__ import annotations

import json

from spikesim import cli


def test_scenes_command_text_and_json(capsys):
    assert cli.main(["scenes"]) == 0
    out = capsys.readouterr().out
    assert "astronaut" in out and "colorchecker" in out and "homography" in out and "dis" in out
    assert cli.main(["scenes", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["default_flow"] == "dis" and "sprites" in data["scenes"]
