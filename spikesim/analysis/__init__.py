"""Noise studies of spike sensors: characterisation, noise budgets, calibration.

EMVA-1288-style characterisation of an integrate-and-fire spike sensor
(transfer curve, inter-spike intervals, SNR, dark counts, dynamic range),
quantization against the ideal asynchronous reference, per-source noise
budgets of a reconstruction, and calibration of the physical noise model to a
capture.  Each study returns an :class:`AnalysisResult`;
:func:`write_report` writes it as Markdown, JSON and PNG.  The command line
is ``spikesim analyze ...`` (``docs/analysis.md``).

Modules: ``theory`` (closed forms), ``capture`` (block-wise reading),
``sweep`` (flat fields), ``transfer``, ``isi``, ``snr``, ``quantization``,
``budget``, ``regions``, ``calibration_config``, ``calibrate`` (steps in
``calibrate_fit`` and ``temporal_fit``), ``fitcheck`` and ``gof_stats``
(goodness of fit), ``accuracy`` and ``short_capture`` (the calibration on
simulated captures), ``report``.
"""

from __future__ import annotations

from spikesim.analysis.accuracy import CALIBRATION_SETTINGS, TOLERANCES, calibration_accuracy
from spikesim.analysis.budget import noise_budget, noise_sources
from spikesim.analysis.calibrate import CalibrationResult, calibrate
from spikesim.analysis.calibration_config import CalibrationConfig
from spikesim.analysis.capture import Capture, as_capture, pixel_counts, pixel_intervals
from spikesim.analysis.isi import isi_statistics
from spikesim.analysis.quantization import quantization_study, saturation_recovery
from spikesim.analysis.regions import detect_regions
from spikesim.analysis.report import AnalysisResult, write_report
from spikesim.analysis.short_capture import short_capture_fidelity
from spikesim.analysis.snr import snr_curve
from spikesim.analysis.transfer import transfer_curve

__all__ = [
    "AnalysisResult",
    "CalibrationConfig",
    "CalibrationResult",
    "CALIBRATION_SETTINGS",
    "Capture",
    "TOLERANCES",
    "as_capture",
    "calibrate",
    "calibration_accuracy",
    "detect_regions",
    "isi_statistics",
    "noise_budget",
    "noise_sources",
    "pixel_counts",
    "pixel_intervals",
    "quantization_study",
    "saturation_recovery",
    "short_capture_fidelity",
    "snr_curve",
    "transfer_curve",
    "write_report",
]
