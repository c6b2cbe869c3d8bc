"""Video scenes: readers on real encoded files and folders, laziness, key frames, bad input."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import spikesim.scenes as sc
from spikesim.errors import SpikeSimFileError, SpikeSimFormatError, SpikeSimValueError
from spikesim.scenes.photometry import SRGB8_LUT

LEVELS = [20 + 30 * i for i in range(7)]


def _frame(i, h=32, w=40):
    img = np.full((h, w, 3), LEVELS[i], np.uint8)
    img[:, :, 2] = 10  # blue channel constant: BGR->RGB order is checked below
    return img


@pytest.fixture()
def clip(tmp_path):
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (40, 32))
    assert writer.isOpened()
    for i in range(7):
        writer.write(_frame(i)[..., ::-1].copy())  # OpenCV writes BGR
    writer.release()
    return path


def test_video_file_count_order_fps_and_lazy(clip):
    v = sc.video(clip)
    assert (v.n_frames, v.height, v.width, v.fps) == (7, 32, 40, 30.0)
    assert v.source.n_decoded == 0  # nothing decoded on open
    f3 = v.frame(3)
    assert v.source.n_decoded == 1
    assert abs(float(f3[..., 0].mean()) - SRGB8_LUT[LEVELS[3]]) < 0.01  # red = level
    assert abs(float(f3[..., 2].mean()) - SRGB8_LUT[10]) < 0.005  # blue = 10
    means = [float(v.frame(i)[..., 0].mean()) for i in (6, 0, 5, 1)]  # random order (seeks)
    assert means[1] < means[3] < means[2] < means[0]
    assert v.source.n_decoded == 5
    # the fps parameter overrides the container rate; the time range selects frames
    w = sc.video(clip, fps=60.0, start_s=2 / 60, stop_s=5 / 60)
    assert w.n_frames == 4 and w.fps == 60.0
    assert abs(float(w.frame(0)[..., 0].mean()) - SRGB8_LUT[LEVELS[2]]) < 0.01


def _write_folder(folder, names, sizes=None):
    folder.mkdir(parents=True, exist_ok=True)
    for i, name in enumerate(names):
        h, w = (sizes or {}).get(i, (32, 40))
        assert cv2.imwrite(str(folder / name), _frame(i, h, w)[..., ::-1].copy())


def test_reds_davis_and_plain_folders(tmp_path):
    _write_folder(tmp_path / "reds" / "000", [f"{i:08d}.png" for i in range(5)])
    reds = sc.video(tmp_path / "reds", sequence="000")
    assert reds.n_frames == 5 and reds.fps == 24.0 and reds.source.n_decoded == 0
    np.testing.assert_allclose(reds.frame(4)[0, 0, 0], SRGB8_LUT[LEVELS[4]])  # png: lossless
    _write_folder(tmp_path / "davis" / "JPEGImages" / "480p" / "bear",
                  [f"{i:05d}.jpg" for i in range(4)])
    davis = sc.video(tmp_path / "davis", sequence="bear")
    assert davis.describe()["source"].endswith("bear") and davis.n_frames == 4
    # natural sort: 2.png comes before 10.png
    _write_folder(tmp_path / "plain", ["1.png", "2.png", "10.png"])
    plain = sc.video(tmp_path / "plain", fps=10)
    order = [float(plain.frame(i)[0, 0, 0]) for i in range(3)]
    assert order == sorted(order)
    # crop then resize, in linear light
    cr = sc.video(tmp_path / "plain", crop=(4, 8, 16, 20), resize=(8, 10))
    assert cr.frame(0).shape == (8, 10, 3)
    with pytest.raises(SpikeSimValueError, match="crop"):
        sc.video(tmp_path / "plain", crop=(30, 0, 16, 20))
    with pytest.raises(SpikeSimValueError, match="sequence"):
        sc.video(tmp_path / "reds", layout="reds")


def test_key_times_and_radiance_agree(tmp_path):
    exact = sc.procedural("coffee", motion="pan", size=(48, 48), speed=72.0)
    v = exact.as_video(24.0, 4)
    keys = v.key_times(0.0, 3 / 24)
    ms = [v.n_intermediate(i) for i in range(3)]
    assert all(m in (2, 3) for m in ms)  # 3 px per frame, 1 px per key frame (flow max: +-1)
    assert len(keys) == sum(ms) + 4
    starts = np.cumsum([0] + [m + 1 for m in ms])
    np.testing.assert_allclose(keys[starts], np.arange(4) / 24)
    np.testing.assert_array_equal(v.radiance(keys[0]), exact.radiance(0.0))
    mid = 0.5 * (keys[1] + keys[2])
    np.testing.assert_allclose(v.radiance(mid), 0.5 * (v.radiance(keys[1]) + v.radiance(keys[2])),
                               atol=1e-6)
    # a chunk's keys bracket the interval and come from the same global grid
    sub = v.key_times(0.05, 0.07)
    assert sub[0] <= 0.05 and sub[-1] >= 0.07 and np.isin(sub, keys).all()
    # after the last frame the last frame is held
    tail = v.key_times(0.12, 0.2)
    assert tail[-1] >= 0.2
    np.testing.assert_array_equal(v.radiance(0.2), v.radiance(3 / 24))
    assert not v.is_static and v.describe()["rendered_from"]["name"] == "coffee"
    # interpolation is far closer to the truth than the frames around it
    t = 1.5 / 24

    def err(x):
        return float(np.abs(x - exact.radiance(t)).mean())

    assert err(v.radiance(t)) < 0.25 * err(v.frame(1))


def test_scene_video_srgb8_is_quantised():
    exact = sc.procedural("ramp", size=(4, 64))
    v = exact.as_video(24.0, 2, srgb8=True)
    np.testing.assert_allclose(v.frame(0), exact.radiance(0), atol=0.005)
    assert len(np.unique(v.frame(0))) <= 64


def test_a_truncated_jpeg_frame_is_refused_not_read_as_grey(tmp_path):
    """OpenCV decodes a cut JPEG with grey where the data stops (libjpeg only warns);
    the frame is refused instead, naming the file. Whole JPEGs (baseline,
    progressive, restart markers, data after the end marker) are read as before."""
    from spikesim.scenes.jpeg_check import jpeg_truncated

    (tmp_path / "jpg").mkdir()
    rng = np.random.default_rng(0)
    for i in range(3):  # textured: a few kB of scan data after the header
        assert cv2.imwrite(str(tmp_path / "jpg" / f"{i}.jpg"),
                           (rng.random((48, 64, 3)) * 255).astype(np.uint8))
    cut = tmp_path / "jpg" / "1.jpg"
    data = cut.read_bytes()
    assert not jpeg_truncated(data) and not jpeg_truncated(data + b"\xff\xda trailer")
    cut.write_bytes(data[:-60])  # the header whole: the size reads, the pixels do not
    v = sc.video(tmp_path / "jpg")
    v.frame(0)
    with pytest.raises(SpikeSimFormatError, match=r"unreadable frame .*1.jpg: a truncated JPEG"):
        v.frame(1)
    img = (rng.random((64, 80, 3)) * 255).astype(np.uint8)
    for flags in ([], [cv2.IMWRITE_JPEG_PROGRESSIVE, 1], [cv2.IMWRITE_JPEG_RST_INTERVAL, 2]):
        ok, buf = cv2.imencode(".jpg", img, flags)
        whole = buf.tobytes()
        assert ok and not jpeg_truncated(whole)
        assert all(jpeg_truncated(whole[:k]) for k in range(2, len(whole) - 1, 7))
    assert not jpeg_truncated(b"not a jpeg")  # left to the decoder


def test_bad_inputs(tmp_path, clip):
    with pytest.raises(SpikeSimFileError, match="does not exist"):
        sc.video(tmp_path / "missing.mp4")
    (tmp_path / "empty").mkdir()
    with pytest.raises(SpikeSimFileError, match="no image frames"):
        sc.video(tmp_path / "empty")
    _write_folder(tmp_path / "mixed", ["0.png", "1.png", "2.png"], sizes={2: (30, 40)})
    with pytest.raises(SpikeSimFormatError, match="mixed frame sizes.*2.png"):
        sc.video(tmp_path / "mixed")
    _write_folder(tmp_path / "broken", ["0.png", "1.png"])
    (tmp_path / "broken" / "2.png").write_bytes(b"this is not a png")
    with pytest.raises(SpikeSimFormatError, match="unreadable frame.*2.png"):
        sc.video(tmp_path / "broken")
    for fps in (0, -24.0, float("nan")):
        with pytest.raises(SpikeSimValueError, match="fps"):
            sc.video(clip, fps=fps)
    _write_folder(tmp_path / "one", ["0.png"])
    with pytest.raises(SpikeSimValueError, match="at least 2 frames"):
        sc.video(tmp_path / "one")
    with pytest.raises(SpikeSimValueError, match="at least 2 frames"):
        sc.video(clip, start_s=6 / 30)
    (tmp_path / "nan").mkdir()
    for i in range(2):
        img = np.full((8, 8, 3), 0.5, np.float32)
        if i == 1:
            img[2, 3, 1] = np.nan
        assert cv2.imwrite(str(tmp_path / "nan" / f"{i}.tif"), img)
    v = sc.video(tmp_path / "nan", linear=True)
    assert v.frame(0)[0, 0, 0] == pytest.approx(0.5)
    with pytest.raises(SpikeSimValueError, match=r"frame 1 of .*nan.*NaN"):
        v.frame(1)
    with pytest.raises(SpikeSimValueError, match="layout"):
        sc.video(clip, layout="youtube")
    with pytest.raises(SpikeSimValueError, match="flow"):
        sc.video(clip, flow="magic")
    with pytest.raises(SpikeSimValueError, match="n_frames"):
        sc.as_video(sc.procedural("flat", size=(4, 4)), 24.0, 1)
    (tmp_path / "junk.avi").write_bytes(b"\x00" * 100)
    with pytest.raises(SpikeSimFormatError, match="unreadable video"):
        sc.video(tmp_path / "junk.avi")


def test_enlarged_and_interpolated_frames_stay_within_the_source_range(tmp_path):
    """Bicubic enlargement and bicubic flow sampling overshoot at saturated edges
    (ground truth reached 1.07 on 8-bit video); they are clipped to the source
    frames' range, so an 8-bit video's radiance and ground truth stay in 0..1."""
    folder = tmp_path / "edges"
    folder.mkdir()
    for i in range(3):
        img = np.zeros((24, 32, 3), np.uint8)
        img[:, 8 + 3 * i: 20 + 3 * i] = 255  # a white bar moving right
        assert cv2.imwrite(str(folder / f"{i:05d}.png"), img)
    v = sc.video(folder, resize=(60, 80))
    assert all(float(v.frame(i).max()) <= 1.0 for i in range(3))
    between = [v.radiance(t) for t in np.linspace(0, 2 / v.fps, 7)]
    assert max(float(r.max()) for r in between) <= 1.0
    assert min(float(r.min()) for r in between) >= 0.0
    assert max(float(r.max()) for r in between) == 1.0  # the bar's white is kept


def test_resize_to_another_aspect_warns_once(tmp_path):
    import warnings

    from spikesim.scenes.video import AspectWarning

    _write_folder(tmp_path / "f", [f"{i:05d}.png" for i in range(3)])  # 32x40 frames
    with pytest.warns(AspectWarning, match=r"resize=\(40, 40\) squashes the 32x40 frames "
                                           r"\(aspect ratio changed by \+25 %\)"):
        sc.video(tmp_path / "f", resize=(40, 40))
    with warnings.catch_warnings():
        warnings.simplefilter("error", AspectWarning)
        sc.video(tmp_path / "f", resize=(64, 80))  # same aspect
        sc.video(tmp_path / "f", resize=(40, 40), crop=(0, 4, 32, 32))  # a square crop


def test_an_unreadable_video_gives_one_line_without_ffmpeg_noise(tmp_path):
    """FFmpeg's log (``moov atom not found``) is silenced; the error says it all."""
    import subprocess
    import sys

    bad = tmp_path / "notes.mp4"
    bad.write_text("not a video\n")
    code = ("import spikesim.scenes as sc\n"
            f"try:\n    sc.video({str(bad)!r})\nexcept Exception as e:\n    print(e)\n")
    env = {k: v for k, v in __import__("os").environ.items() if k != "OPENCV_FFMPEG_LOGLEVEL"}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=120)
    assert "unreadable video" in run.stdout
    assert "moov" not in run.stderr, run.stderr


def test_simulating_past_the_video_end_warns_once(tmp_path):
    """A stream longer than its video holds the last frame, as documented, and says so
    once; a stream within the video does not warn."""
    import warnings

    import spikesim as ss
    from spikesim.scenes.video import VideoEndWarning

    _write_folder(tmp_path / "f", [f"{i:05d}.png" for i in range(3)])  # 3 frames
    scene = sc.video(tmp_path / "f", fps=1000.0)  # ends at 2 ms
    sensor = ss.Sensor(height=32, width=40, cfa=None, clock_hz=20_000.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", VideoEndWarning)
        ss.simulate(scene, sensor, 40, gt_readouts=[])  # 2 ms: within
    with pytest.warns(VideoEndWarning, match=r"ends at 0.002 s \(3 frames at 1000 fps\) and "
                                             r"0.01 s are asked for") as caught:
        ss.simulate(scene, sensor, 200, gt_readouts=[])
    assert sum(issubclass(w.category, VideoEndWarning) for w in caught) == 1


@pytest.mark.parametrize("chunk", [16, 64, None])
def test_the_video_end_warning_names_the_whole_request_whatever_the_chunks(tmp_path, chunk):
    """The warning names the length the run asks for (10 ms here), not the end of the
    first chunk that goes past the video (0.8 ms or 3.2 ms chunks); each run says its own."""
    import warnings

    import spikesim as ss
    from spikesim.scenes.video import VideoEndWarning

    _write_folder(tmp_path / "f", [f"{i:05d}.png" for i in range(3)])  # ends at 2 ms
    scene = sc.video(tmp_path / "f", fps=1000.0)
    sensor = ss.Sensor(height=32, width=40, cfa=None, clock_hz=20_000.0)
    with pytest.warns(VideoEndWarning, match=r"and 0.01 s are asked for") as caught:
        ss.simulate(scene, sensor, 200, gt_readouts=[], chunk_readouts=chunk)
    assert sum(issubclass(w.category, VideoEndWarning) for w in caught) == 1
    with pytest.warns(VideoEndWarning, match=r"and 0.02 s are asked for") as caught:
        list(ss.simulate_chunks(scene, sensor, 400, gt_readouts=[], chunk_readouts=chunk))
    assert sum(issubclass(w.category, VideoEndWarning) for w in caught) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", VideoEndWarning)
        scene.check_duration(0.003)  # within one frame interval of the last frame
