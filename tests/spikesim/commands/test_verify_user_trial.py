"""``spikesim verify`` after a user trial: unchecked files are not ok, the summary counts
each kind, the exit status tells "all verified" from "some not checked", and a damaged
file of a dataset folder gets advice on remaking it."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from spikesim.cli import main
from spikesim.commands.verify import EXIT_NOTHING, EXIT_UNCHECKED
from spikesim.io import verify, write_dat, write_h5


def _unknown_size_dat(folder, name="trunc.dat"):
    """A .dat whose size fits no known sensor (a truncated 64x64 capture)."""
    write_dat(folder / "whole.dat", np.zeros((10, 64, 64), np.uint8))
    data = (folder / "whole.dat").read_bytes()
    (folder / "whole.dat").unlink()
    (folder / name).write_bytes(data[:-100])
    return folder / name


def test_an_unchecked_dat_is_not_ok(tmp_path, capsys):
    path = _unknown_size_dat(tmp_path)
    assert main(["verify", str(path)]) == EXIT_UNCHECKED == 3
    out = capsys.readouterr().out
    assert "UNCHECKED" in out and "1 of 1 file(s) ok" not in out
    assert "1 file(s): 0 checked, 0 ok, 0 damaged, 1 unchecked" in out
    assert "--height and --width" in out.splitlines()[-1]


def test_an_unchecked_dat_in_json_and_python(tmp_path, capsys):
    path = _unknown_size_dat(tmp_path)
    assert main(["verify", str(path), "--json"]) == EXIT_UNCHECKED
    (report,) = json.loads(capsys.readouterr().out)
    assert report["ok"] is False and report["status"] == "unchecked" and not report["problems"]
    (same,) = verify(path)
    assert same == report


def test_giving_the_size_checks_it(tmp_path, capsys):
    path = _unknown_size_dat(tmp_path)
    assert main(["verify", str(path), "--height", "64", "--width", "64"]) == 1
    out = capsys.readouterr().out
    assert "DAMAGED" in out and "1 file(s): 1 checked, 0 ok, 1 damaged, 0 unchecked" in out


def test_a_folder_with_ok_unchecked_and_damaged_files(tmp_path, make_stream, capsys):
    write_h5(tmp_path / "good.h5", make_stream(n=40))
    _unknown_size_dat(tmp_path, "odd.dat")
    (tmp_path / "bad.h5").write_bytes((tmp_path / "good.h5").read_bytes()[:3000])
    assert main(["verify", str(tmp_path)]) == 1  # damage outranks unchecked
    out = capsys.readouterr().out
    assert "3 file(s): 2 checked, 1 ok, 1 damaged, 1 unchecked" in out
    (tmp_path / "bad.h5").unlink()
    assert main(["verify", str(tmp_path)]) == EXIT_UNCHECKED
    assert "2 file(s): 1 checked, 1 ok, 0 damaged, 1 unchecked" in capsys.readouterr().out
    (tmp_path / "odd.dat").unlink()
    assert main(["verify", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "1 file(s): 1 checked, 1 ok, 0 damaged, 0 unchecked" in out
    assert "not verified" not in out


def _dataset(tmp_path, make_stream, marker):
    """A dataset root as ``spikesim dataset`` leaves it, with one damaged sequence."""
    root = tmp_path / "ds"
    (root / "train").mkdir(parents=True)
    if marker == "plan.json":
        tasks = [{"file": "train/seq0.h5"}, {"file": "train/seq1.h5"}]  # as a build plans
        (root / "plan.json").write_text(json.dumps({"manifest": "my.toml", "tasks": tasks}))
    else:
        (root / marker).write_text("{}")
    write_h5(root / "train" / "seq0.h5", make_stream(n=40))
    bad = root / "train" / "seq1.h5"
    bad.write_bytes((root / "train" / "seq0.h5").read_bytes()[:3000])
    return root, bad


@pytest.mark.parametrize("marker", ["plan.json", "build_summary.json"])
def test_a_damaged_dataset_file_says_how_to_remake_it(tmp_path, make_stream, capsys, marker):
    root, bad = _dataset(tmp_path, make_stream, marker)
    assert main(["verify", str(root)]) == 1
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("DAMAGED"))
    assert str(bad) in line and "to fix:" in line
    assert f"delete it (rm '{bad}')" in line and "run the same build again" in line
    manifest = "my.toml" if marker == "plan.json" else "MANIFEST"
    assert f"spikesim dataset {manifest} --out '{root}'" in line
    assert "remakes the missing file" in line
    (report,) = [r for r in verify(root) if not r["ok"]]
    assert report["advice"] in line


def test_a_damaged_file_of_no_dataset_gets_no_dataset_advice(tmp_path, make_stream, capsys):
    write_h5(tmp_path / "a.h5", make_stream(n=40))
    (tmp_path / "b.h5").write_bytes((tmp_path / "a.h5").read_bytes()[:3000])
    assert main(["verify", str(tmp_path / "b.h5")]) == 1
    out = capsys.readouterr().out
    assert "DAMAGED" in out and "spikesim dataset" not in out
    assert "advice" not in verify(tmp_path / "b.h5")[0]


@pytest.mark.parametrize("flags", [[], ["--json"]])
def test_nothing_to_verify_is_a_usage_error_not_damage(tmp_path, capsys, flags):
    """A folder with no spike file (at any depth) or a path that does not exist: one line
    on stderr saying so and exit 2, never 1 ("damaged")."""
    (tmp_path / "empty").mkdir()
    (tmp_path / "notes" / "sub").mkdir(parents=True)
    (tmp_path / "notes" / "sub" / "readme.txt").write_text("no spikes here")
    for path, words in ((tmp_path / "empty", "no .h5, .hdf5 or .dat file found in the folder"),
                        (tmp_path / "notes", "no .h5, .hdf5 or .dat file found in the folder"),
                        (tmp_path / "missing", "no such file or folder"),
                        (tmp_path / "notes" / "sub" / "readme.txt", "is not a spike file")):
        assert main(["verify", str(path), *flags]) == EXIT_NOTHING == 2
        cap = capsys.readouterr()
        assert cap.out == "" and len(cap.err.strip().splitlines()) == 1, cap
        assert cap.err.startswith("spikesim verify: error: ") and words in cap.err
        assert str(path) in cap.err


def test_a_folder_holding_only_a_killed_writers_temporary_is_listed_not_empty(tmp_path, capsys):
    import subprocess

    (tmp_path / "ds").mkdir()
    subprocess.run([sys.executable, "-c", "import sys; from pathlib import Path; "
                    "from spikesim.io.atomic import temp_name_for; "
                    "temp_name_for(Path(sys.argv[1])).write_bytes(b'half written')",
                    str(tmp_path / "ds" / "seq.h5")], check=True)  # a writer now gone
    assert main(["verify", str(tmp_path / "ds")]) == 0
    assert "stale temporary" in capsys.readouterr().out
