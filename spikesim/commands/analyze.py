"""``spikesim analyze STUDY``: noise studies written as a Markdown/JSON/PNG report.

Studies: ``transfer``, ``isi``, ``snr``, ``quantization``, ``budget``,
``calibrate`` (fit a sensor to a capture, mono or colour, with or without flat
regions), ``calibration-accuracy`` (the
calibration proven on simulated captures) and ``calibration-short`` (short
moving captures: calibrated against default re-simulation).  The work is done by
:mod:`spikesim.analysis`; this module only parses and prints.
"""

from __future__ import annotations

import re
from pathlib import Path

from spikesim.errors import SpikeSimFileError, SpikeSimValueError, bad_value

__all__ = ["register"]


def _floats(text: str | None, name: str):
    if text is None:
        return None
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise bad_value(name, text, "comma-separated numbers, e.g. 0,0.1,0.5") from None


def _size(text: str, name: str = "--size") -> tuple[int, int]:
    from spikesim.cli_guard import parse_size

    return parse_size(text, name, example="32x32")


def _sensor(args):
    from spikesim.commands.simulate import load_sensor, parse_overrides

    return load_sensor(args.sensor, parse_overrides(args.set))


def _common(p, sensor_default: str = "ideal") -> None:
    p.add_argument("--out", required=True, help="output folder for NAME.md, NAME.json, NAME.png")
    p.add_argument("--sensor", default=sensor_default,
                   help=f"sensor preset or a sensor .json file (default {sensor_default})")
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                   help="override a sensor field, e.g. --set reset=zero --set cfa=mono, or "
                        "a field of its noise model: --set noise.electrons_per_threshold=300")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-progress", dest="progress", action="store_false",
                   help="no progress bars")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "analyze", help="noise studies: transfer, isi, snr, quantization, budget, calibrate",
        description="Sensor characterisation, noise budgets and calibration; each study writes "
                    "a Markdown report, JSON figures and a PNG plot into --out.")
    sub = p.add_subparsers(dest="study", metavar="STUDY", required=True)

    s = sub.add_parser("transfer", help="mean firing rate vs flat-field radiance")
    _common(s)
    s.add_argument("--levels", default=None, help="radiances, comma-separated (1 = full scale)")
    s.add_argument("--readouts", type=int, default=2000)
    s.add_argument("--size", default="32x32")
    s.add_argument("--window", type=int, default=100, help="readouts per temporal window")
    s.set_defaults(func=_run_transfer)

    s = sub.add_parser("isi", help="inter-spike-interval statistics vs radiance")
    _common(s)
    s.add_argument("--levels", default=None)
    s.add_argument("--readouts", type=int, default=5000)
    s.add_argument("--size", default="16x16")
    s.set_defaults(func=_run_isi)

    s = sub.add_parser("snr", help="SNR of TFP/TFI, dark-count rate, dynamic range")
    _common(s)
    s.add_argument("--levels", default=None)
    s.add_argument("--windows", default="11,41,161", help="TFP windows, comma-separated")
    s.add_argument("--readouts", type=int, default=3220)
    s.add_argument("--size", default="24x24")
    s.set_defaults(func=_run_snr)

    s = sub.add_parser("quantization", help="clocked vs ideal asynchronous; reset modes")
    _common(s)
    s.add_argument("--levels", default=None)
    s.add_argument("--readouts", type=int, default=2000)
    s.add_argument("--size", default="16x16")
    s.add_argument("--window", type=int, default=41)
    s.set_defaults(func=_run_quantization)

    s = sub.add_parser("budget", help="PSNR cost of each noise source")
    _common(s, sensor_default="physical")
    s.add_argument("scene", nargs="?", default="astronaut", help="built-in scene name")
    s.add_argument("--motion", default=None)
    s.add_argument("--readouts", type=int, default=400)
    s.add_argument("--size", default="64x64")
    s.add_argument("--method", default="tfp",
                   help="tfp (default), tfi, or a method of an installed reconstruction "
                        "package, e.g. spikejdd's tfp+menon2007 or sjdd")
    s.add_argument("--window", type=int, default=41)
    s.add_argument("--centers", type=int, default=4, help="readouts reconstructed")
    s.set_defaults(func=_run_budget)

    s = sub.add_parser(
        "calibrate", help="fit the physical noise model to a capture",
        description="Fit the physical noise model to a capture: from its flat regions, or "
                    "without one from per-pixel temporal statistics and spatial residuals; "
                    "a colour capture plane by plane (an HDF5 file records its colour filter, "
                    "a .dat needs --cfa: a colour .dat without it is refused).  Writes "
                    "calibration.md/.json/.png (parameters with their status, the calibrated "
                    "and default re-simulations side by side) and sensor.json.")
    s.add_argument("capture", help="a .dat capture, or a spikesim .h5 file or folder")
    s.add_argument("--out", required=True)
    s.add_argument("--dark-mask", default=None, help=".npy (H, W) bool mask of dark pixels")
    s.add_argument("--flat-masks", default=None,
                   help=".npy (H, W) int labels (0 = none) or (K, H, W) bool masks")
    s.add_argument("--levels", default=None,
                   help="radiance of each flat region, comma-separated (1 = full scale)")
    s.add_argument("--no-detect", dest="detect", action="store_false",
                   help="do not detect regions automatically when no mask is given")
    s.add_argument("--reset", choices=("modulo", "subtract"), default=None,
                   help="the capture's reset mode (default: what a spikesim capture records, "
                        "else modulo); zero-reset captures cannot be calibrated")
    s.add_argument("--electrons", type=float, default=None,
                   help="known electrons per threshold (then σ_t is fitted)")
    s.add_argument("--sigma-t", type=float, default=0.006,
                   help="assumed comparator jitter when E is fitted (default 0.006)")
    s.add_argument("--mismatch-split", type=float, default=None,
                   help="threshold-mismatch share of the response spread (default SCSim ratio)")
    s.add_argument("--full-scale-rate", type=float, default=None,
                   help="known rate at radiance 1 in spikes per readout (e.g. the chip's rate "
                        "at full white): places flat regions of unknown radiance (default: the "
                        "brightest region is full scale)")
    s.add_argument("--no-charge-noise", dest="charge_noise", action="store_false",
                   help="keep charge_noise_electrons at 0 (default: fitted when the interval CV "
                        "grows significantly with the interval length)")
    s.add_argument("--max-readouts", type=int, default=None)
    s.add_argument("--no-check", dest="check", action="store_false",
                   help="skip the re-simulation goodness-of-fit check")
    s.add_argument("--seed", type=int, default=1, help="seed of the re-simulation")
    s.add_argument("--no-progress", dest="progress", action="store_false")
    from spikesim.commands._io_common import add_source_options

    add_source_options(s)
    s.set_defaults(func=_run_calibrate)

    s = sub.add_parser("calibration-accuracy",
                       help="recover known parameters from simulated captures (table)")
    s.add_argument("--out", required=True)
    s.add_argument("--size", default="64x64")
    s.add_argument("--readouts", type=int, default=10_000)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--name", default="calibration_accuracy",
                   help="file stem (default calibration_accuracy)")
    s.add_argument("--no-progress", dest="progress", action="store_false")
    s.set_defaults(func=_run_accuracy)

    s = sub.add_parser("calibration-short",
                       help="calibrate short moving captures: calibrated vs default re-simulation")
    s.add_argument("--out", required=True)
    s.add_argument("--size", default="48x128")
    s.add_argument("--readouts", type=int, default=200)
    s.add_argument("--seeds", default="0,1,2", help="comma-separated simulation seeds")
    s.add_argument("--no-progress", dest="progress", action="store_false")
    s.set_defaults(func=_run_short)


def _write(result, args, name=None) -> int:
    from spikesim.analysis.report import write_report

    paths = write_report(result, args.out, name=name)
    for note in result.notes:
        print(note)
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    return 0


def _run_transfer(args) -> int:
    from spikesim.analysis.transfer import DEFAULT_LEVELS, transfer_curve

    res = transfer_curve(_sensor(args), _floats(args.levels, "--levels") or DEFAULT_LEVELS,
                         args.readouts, _size(args.size), args.window, args.seed, args.progress)
    return _write(res, args)


def _run_isi(args) -> int:
    from spikesim.analysis.isi import DEFAULT_ISI_LEVELS, isi_statistics

    res = isi_statistics(_sensor(args), _floats(args.levels, "--levels") or DEFAULT_ISI_LEVELS,
                         args.readouts, _size(args.size), args.seed, args.progress)
    return _write(res, args)


def _run_snr(args) -> int:
    from spikesim.analysis.snr import DEFAULT_SNR_LEVELS, snr_curve

    wins = [int(w) for w in _floats(args.windows, "--windows")]
    res = snr_curve(_sensor(args), _floats(args.levels, "--levels") or DEFAULT_SNR_LEVELS, wins,
                    args.readouts, _size(args.size), args.seed, progress=args.progress)
    return _write(res, args)


def _run_quantization(args) -> int:
    from spikesim.analysis.quantization import DEFAULT_Q_LEVELS, quantization_study

    res = quantization_study(_sensor(args), _floats(args.levels, "--levels") or DEFAULT_Q_LEVELS,
                             args.readouts, _size(args.size), args.window, args.seed,
                             progress=args.progress)
    return _write(res, args)


def _run_budget(args) -> int:
    from spikesim.analysis.budget import noise_budget

    res = noise_budget(args.scene, _sensor(args), args.readouts, args.seed, args.method,
                       args.window, args.centers, _size(args.size), args.motion, args.progress)
    return _write(res, args)


def _load_npy(path: str | None, name: str):
    if path is None:
        return None
    import numpy as np

    p = Path(path)
    if not p.is_file():
        raise SpikeSimFileError(f"{name}: no such file {path!r}")
    try:
        return np.load(p, allow_pickle=False)
    except (ValueError, OSError, EOFError):  # (numpy's advice on pickles does not apply)
        raise bad_value(name, path, "a .npy file of a numeric array (numpy.save of a mask or "
                        "label image)") from None


#: calibrate()'s parameters and CalibrationConfig's fields -> calibrate's options.
_CALIBRATE_OPTIONS = {
    "dark_mask": "--dark-mask", "flat_masks": "--flat-masks", "flat_levels": "--levels",
    "electrons_per_threshold": "--electrons", "temporal_threshold_noise": "--sigma-t",
    "mismatch_split": "--mismatch-split", "full_scale_rate": "--full-scale-rate",
    "max_readouts": "--max-readouts", "check_seed": "--seed"}
_PARAMETER = re.compile(r"(?<![\w.-])(" + "|".join(_CALIBRATE_OPTIONS) + r")\b")

def _calibrate_error(exc):
    """A calibrate error naming the command line's options (``--flat-masks``,
    ``--sigma-t``) where the library names its parameters (``flat_masks``,
    ``temporal_threshold_noise``)."""
    text = _PARAMETER.sub(lambda m: _CALIBRATE_OPTIONS[m.group(1)], str(exc))
    text = re.sub(r"^(--[a-z-]+)\.shape=", r"\1 of shape ", text)  # --dark-mask of shape (4, 4)
    if overlap := re.match(r"masks='(.*)' is invalid: expected (.*)", text):
        text = (f"the regions of --dark-mask and --flat-masks overlap ({overlap[1]}): "
                f"expected {overlap[2]}")
    elif option := re.match(r"(--[a-z-]+)=", text):  # None: the option left out
        text = text.removesuffix(", or None").replace("expected None",
                                                      f"expected no {option[1]}")
    return type(exc)(text)


def _run_calibrate(args) -> int:
    from spikesim.analysis.calibrate import DEFAULT_MISMATCH_SPLIT, calibrate
    from spikesim.analysis.report import write_report
    from spikesim.commands._io_common import source_from_args
    from spikesim.errors import SpikeSimError
    from spikesim.io.source import is_dat

    if not args.detect and args.dark_mask is None and args.flat_masks is None:
        raise SpikeSimValueError("--no-detect needs --flat-masks (and --dark-mask) to give "
                                 "the regions, or leave --no-detect out to have them detected")
    src = source_from_args(args, args.capture)
    try:
        res = calibrate(
            src, dark_mask=_load_npy(args.dark_mask, "--dark-mask"),
            flat_masks=_load_npy(args.flat_masks, "--flat-masks"),
            flat_levels=_floats(args.levels, "--levels"), detect=args.detect,
            electrons_per_threshold=args.electrons, temporal_threshold_noise=args.sigma_t,
            mismatch_split=DEFAULT_MISMATCH_SPLIT if args.mismatch_split is None
            else args.mismatch_split, full_scale_rate=args.full_scale_rate,
            fit_charge_noise=args.charge_noise, max_readouts=args.max_readouts,
            check=args.check, check_seed=args.seed, reset=args.reset, progress=args.progress,
            cfa=args.cfa if is_dat(args.capture) else None,  # HDF5 records its own
            option_names={"flat_levels": "--levels", "reset": "--reset",
                          "full_scale_rate": "--full-scale-rate", "cfa": "--cfa"})
    except SpikeSimError as exc:  # name the options, not calibrate()'s parameters
        named = _calibrate_error(exc)
        if args.max_readouts is not None and str(named).startswith("capture length="):
            named = type(named)(f"{named} (--max-readouts {args.max_readouts} shortens it)")
        raise named from None
    paths = write_report(res, args.out)
    sensor_path = Path(args.out) / "sensor.json"
    sensor_path.write_text(res.sensor.to_json() + "\n")
    for note in res.notes:
        print(note)
    print("wrote " + ", ".join(str(p) for p in [*paths.values(), sensor_path]))
    return 0


def _run_accuracy(args) -> int:
    from spikesim.analysis.accuracy import calibration_accuracy

    res = calibration_accuracy(size=_size(args.size), n_readouts=args.readouts, seed=args.seed,
                               progress=args.progress)
    return _write(res, args, name=args.name)


def _run_short(args) -> int:
    from spikesim.analysis.short_capture import short_capture_fidelity

    try:
        seeds = [int(v) for v in args.seeds.split(",") if v.strip()]
    except ValueError:
        raise bad_value("--seeds", args.seeds, "comma-separated integers, e.g. 0,1,2") from None
    res = short_capture_fidelity(size=_size(args.size), n_readouts=args.readouts, seeds=seeds,
                                 progress=args.progress)
    return _write(res, args)
