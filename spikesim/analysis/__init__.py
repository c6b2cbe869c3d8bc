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
``budget``, ``planes`` (colour planes, the colour test), ``regions`` and
``calibration_regions`` (regions per plane), ``calibration_config``,
``calibrate`` (steps in ``calibrate_fit``, ``temporal_fit`` and, without a
flat region, ``natural_fit``), ``fitcheck``, ``gof_stats`` and ``gof_report``
(goodness of fit), ``calibration_report``, ``accuracy``, ``short_capture`` and
``natural_capture`` (the calibration on simulated captures), ``report``.
"""

from __future__ import annotations

from spikesim.analysis.accuracy import CALIBRATION_SETTINGS, TOLERANCES, calibration_accuracy
from spikesim.analysis.budget import noise_budget, noise_sources
from spikesim.analysis.calibrate import CalibrationResult, calibrate
from spikesim.analysis.calibration_config import CalibrationConfig
from spikesim.analysis.capture import Capture, as_capture, pixel_counts, pixel_intervals
from spikesim.analysis.isi import isi_statistics
from spikesim.analysis.natural_capture import natural_capture
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
    "natural_capture",
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
