"""Evaluation harness and CLI on a tiny simulated dataset."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

import spikesim as ss
from spikejdd import evaluate
from spikejdd.cli import main
from spikesim.errors import SpikeSimValueError
from spikesim.io import write_h5


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("evalset")
    yy, xx = np.mgrid[0:20, 0:24] / 24.0
    for i, cfa in enumerate(("RGGB", "GBRG")):
        img = np.stack([0.2 + 0.6 * xx, 0.3 + 0.5 * yy, 0.7 - 0.4 * xx * yy], -1)  # smooth
        sensor = ss.Sensor(height=20, width=24, cfa=cfa)
        stream = ss.simulate(ss.scenes.Static(img), sensor, n_readouts=50, seed=0,
                             gt_readouts=[25])
        write_h5(d / f"seq{i}.h5", stream)
    return d


def test_run_scores_and_times(data_dir):
    frames = evaluate.frames_from_dataset(data_dir, context=41)
    assert len(frames) == 2 and frames[0].spikes.shape == (41, 20, 24)
    res = evaluate.run(frames, ["tfp+bilinear", "tfp21+menon2007"], repeats=2, progress=False)
    assert len(res["rows"]) == 4
    s = res["summary"]["tfp21+menon2007"]["all"]
    assert s["frames"] == 2 and s["ms_per_frame"] > 0
    assert 15 < s["PSNR[linear]"] < 60 and 0 < s["SSIM-gauss11[srgb]"] <= 1
    with pytest.raises(SpikeSimValueError, match="method"):
        evaluate.run(frames, ["nope"], progress=False)
    with pytest.raises(SpikeSimValueError, match="repeats"):
        evaluate.run(frames, ["tfp+bilinear"], repeats=0, progress=False)


def test_cli_writes_json_md_png(data_dir, tmp_path, capsys):
    out = tmp_path / "r"
    rc = main(["evaluate", "--data", str(data_dir), "--methods", "tfp+bilinear,tfi+bilinear",
               "--repeats", "1", "--out", str(out), "--quiet"])
    assert rc == 0
    res = json.loads(out.with_suffix(".json").read_text())
    assert set(res["summary"]) == {"tfp+bilinear", "tfi+bilinear"}
    assert "PSNR[linear] per sequence" in out.with_suffix(".md").read_text()
    assert out.with_suffix(".png").read_bytes()[:4] == b"\x89PNG"
    assert main(["evaluate", "--data", str(data_dir), "--methods", "bogus", "--out",
                 str(out), "--quiet"]) == 1
    assert "bogus" in capsys.readouterr().err
    assert main(["methods"]) == 0


def test_group_columns_sort_numbers_by_value():
    from spikejdd.evaluate import _natural

    assert sorted(["GN0", "GN10", "GN15", "GN5", "GPN-rand"], key=_natural) == [
        "GN0", "GN5", "GN10", "GN15", "GPN-rand"]


@pytest.mark.parametrize("size", ["0x64", "64x0", "ax8"])
def test_cli_bad_sweep_size_names_the_option(size, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["evaluate", "--sweep", "--size", size])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"--size={size!r} is invalid: expected HxW" in err and "height=" not in err


def test_frames_below_the_ssim_window_are_refused_up_front():
    """A sweep or run on frames under 11×11 pixels fails before any simulation or
    warm-up, naming the size, instead of in the SSIM after the work."""
    from spikejdd.evaluate import Frame, run, sweep

    with pytest.raises(SpikeSimValueError, match=r"size='4x16 pixels'.*at least 11x11"):
        sweep(["tfp+bilinear"], size=(4, 16), progress=False)
    tiny = Frame("tiny", 5, np.zeros((9, 8, 8), np.uint8), 4, "RGGB", 0.5,
                 np.zeros((8, 8, 3), np.float32))
    with pytest.raises(SpikeSimValueError, match=r"frames \(tiny\)='8x8 pixels'"):
        run([tiny], ["tfp+bilinear"], progress=False)


def test_per_sequence_frames_of_back_to_back_windows(tmp_path):
    """A dataset sequence of three 39-readout windows (GT at 19, 58, 97 of 117):
    by default every asked-for frame is scored with the widest context that fits
    them all (39); an explicit 41 scores the middle one and warns with the count
    and the context that would score them all."""
    sensor = ss.Sensor(height=16, width=24, cfa="RGGB")
    scene = ss.scenes.Static(np.full((16, 24), 0.4, np.float32))
    write_h5(tmp_path / "seq.h5", ss.simulate(scene, sensor, 117, gt_readouts=[19, 58, 97]))
    frames = evaluate.frames_from_dataset(tmp_path, per_sequence=3)
    assert [(f.readout, f.spikes.shape[0], f.center) for f in frames] == [
        (19, 39, 19), (58, 39, 19), (97, 39, 19)]
    assert [f.readout for f in evaluate.frames_from_dataset(tmp_path)] == [58]  # 41 fits it
    with pytest.warns(UserWarning, match="context=41 leaves out 2 of the GT frames asked for.*"
                                         "at most 39 readouts"):
        frames = evaluate.frames_from_dataset(tmp_path, context=41, per_sequence=3)
    assert [f.readout for f in frames] == [58]


def test_panel_labels_wrap_instead_of_cutting_alike():
    """Long method names wrap at + : @ / instead of being cut, so two methods that
    share a long prefix keep labels that differ."""
    tile = np.full((64, 96, 3), 0.5)
    names = ["tfp+menon2007+nlm", "tfp+menon2007+bilateral"]
    wide = evaluate._text_width("tfp+menon2007+")
    assert evaluate._wrap_label(names[0], wide) == ["tfp+menon2007+", "nlm"]
    assert evaluate._wrap_label("sjdd@runs/mine/best.pt", wide) == ["sjdd@runs/mine/",
                                                                   "best.pt"]
    long = "mym:good_with_a_really_long_descriptive_method_name"
    lines = evaluate._wrap_label(long, 92)
    assert "".join(lines) == long and max(map(evaluate._text_width, lines)) <= 92
    panel = evaluate.panel_image([tile, tile], names)
    strip = panel.shape[0] - 64  # 64×96 tiles are not enlarged; the label strip is above
    assert strip % 14 == 0 and strip >= 28  # wrapped to two lines or more
    w = (panel.shape[1] - 2) // 2
    assert not np.array_equal(panel[:strip, :w], panel[:strip, w + 2:])


def test_report_says_torch_was_not_used_by_classical_methods(data_dir, tmp_path):
    """torch's default thread count is not reported as the evaluation's when no
    method used torch (a fresh process: nothing else has imported it)."""
    import subprocess
    import sys

    out = tmp_path / "r"
    code = ("from spikejdd.cli import main; import sys; sys.exit(main(['evaluate', '--data', "
            f"{str(data_dir)!r}, '--methods', 'tfp+bilinear', '--repeats', '1', '--out', "
            f"{str(out)!r}, '--quiet']))")
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)
    md = out.with_suffix(".md").read_text()
    assert "torch threads per process: torch not used" in md
    assert "thread(s)" not in md.split("Device:")[0]  # nor in the machine line


def test_a_file_without_ground_truth_is_named_as_such(tmp_path, capsys):
    """A stream without GT (a converted .dat) cannot be scored: the error says so."""
    import spikesim as ss
    from spikejdd.cli import main

    sensor = ss.Sensor(height=16, width=16, cfa="RGGB")
    stream = ss.simulate(ss.scenes.procedural("astronaut", size=(16, 16)), sensor, 60,
                         gt_readouts=[])
    ss.io.write_h5(tmp_path / "nogt.h5", stream)
    assert main(["evaluate", "--data", str(tmp_path / "nogt.h5"), "--methods", "tfp+bilinear",
                 "--out", str(tmp_path / "r"), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "holds no ground truth" in err and "context=" not in err


def test_an_out_folder_holds_the_report(tmp_path, capsys):
    """--out naming a folder (existing, or ending with /) writes evaluation.* inside it,
    not a report beside it."""
    import spikesim as ss
    from spikejdd.cli import main

    sensor = ss.Sensor(height=16, width=16, cfa="RGGB")
    stream = ss.simulate(ss.scenes.procedural("astronaut", size=(16, 16)), sensor, 60)
    ss.io.write_h5(tmp_path / "s.h5", stream)
    (tmp_path / "there").mkdir()
    for out in (str(tmp_path / "there"), str(tmp_path / "new") + "/"):
        assert main(["evaluate", "--data", str(tmp_path / "s.h5"), "--methods", "tfp+bilinear",
                     "--out", out, "--quiet", "--repeats", "1"]) == 0
        folder = tmp_path / out.rstrip("/").split("/")[-1]
        assert sorted(p.name for p in folder.glob("evaluation.*")) == [
            "evaluation.json", "evaluation.md", "evaluation.png"]
    assert not (tmp_path / "there.json").exists()


class _Killed(BaseException):
    """Stands for SIGKILL in the middle of writing a report (nothing after it runs)."""


def _report_state(stem):
    """(run id of stem.json or None, stem.md text, run id note of stem.png, panel names)."""
    from PIL import Image

    js = stem.with_suffix(".json")
    run_id = json.loads(js.read_text())["run_id"] if js.exists() else None
    with Image.open(stem.with_suffix(".png")) as png:
        note = png.info.get("Description", "")
    panels = sorted(p.name for p in (stem.parent / f"{stem.name}_panels").iterdir())
    return run_id, stem.with_suffix(".md").read_text(), note, panels


def test_a_report_cut_short_never_pairs_new_and_old_files(data_dir, tmp_path, monkeypatch):
    """write_report's files are one set: a crash while writing them leaves the earlier
    report whole; a kill while renaming them into place leaves no .json (the mark of a
    whole set); a .json always has the run id of the .md and .png beside it."""
    frames = evaluate.frames_from_dataset(data_dir, context=41)
    outputs: dict = {}
    res = evaluate.run(frames, ["tfp+bilinear"], repeats=1, progress=False, outputs=outputs)
    stem = tmp_path / "rep"

    def write(panels=6):
        return evaluate.write_report(res, ["tfp+bilinear"], stem, frames=frames,
                                     outputs=outputs, panels=panels)

    write()
    first, md, note, panels = _report_state(stem)
    assert first in md and first in note and len(panels) == 2
    # a crash while the PNG is drawn (the .json and .md written before it): nothing changes
    real_scatter = evaluate._scatter

    def scatter_then_crash(*args, **kwargs):
        real_scatter(*args, **kwargs)
        raise _Killed

    monkeypatch.setattr(evaluate, "_scatter", scatter_then_crash)
    with pytest.raises(_Killed):
        write()
    monkeypatch.undo()
    assert _report_state(stem) == (first, md, note, panels)
    # killed after k of the 5 renames (2 panels, PNG, Markdown, JSON last): no .json
    real_replace = os.replace
    for k in range(5):
        done = []

        def replace_then_kill(src, dst, k=k, done=done):
            if len(done) == k:
                raise _Killed
            done.append(dst)
            real_replace(src, dst)

        monkeypatch.setattr(os, "replace", replace_then_kill)
        with pytest.raises(_Killed):
            write()
        monkeypatch.undo()
        assert _report_state(stem)[0] is None, k
        assert not [p for p in tmp_path.rglob(".*") if ".tmp-" in p.name]
    # a whole run again: one run id throughout, and the earlier panels gone
    write(panels=1)
    run_id, md, note, panels = _report_state(stem)
    assert run_id not in (None, first) and run_id in md and run_id in note
    assert len(panels) == 1 and f"rep_panels/{panels[0]}" in md
