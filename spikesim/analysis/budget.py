"""Noise budget: the reconstruction error each noise source costs.

For a scene and a noisy sensor the stream is simulated (same seed each time,
so every run draws identical random numbers for the sources it shares, see
:mod:`spikesim.rng`):

* **all**: every source of the sensor's noise model on;
* **all − s**: source ``s`` switched off, the others on (one run per source);
* **none**: the clean twin of the *all* run (same seed and initial state).

Each stream is reconstructed at the same readouts and scored against the
ground truth with PSNR (peak 1, clamp to [0, 1], no crop; docs/architecture.md, Conventions).

Cost of a source (dB): ``cost_s = PSNR(all − s) − PSNR(all)``; total cost
``PSNR(none) − PSNR(all)``.  How costs "sum": decibels do not add, but for
independent, additive noise the *excess mean squared errors* do.  With
``ΔMSE_s = MSE(all) − MSE(all − s)`` and ``ΔMSE = MSE(all) − MSE(none)``, the
report gives each source's share ``ΔMSE_s/ΔMSE`` and the **interaction**
``ΔMSE − Σ_s ΔMSE_s`` (zero when the sources' errors are independent and
additive; positive or negative when they interact, e.g. through clipping,
saturation or the one-spike-per-readout limit).

Reconstruction: ``"tfp"`` (default, window ``window``) or ``"tfi"`` from
:mod:`spikesim.estimate`, scored on the sensor's colour mosaic; any callable
``fn(spikes, cfa, center, rate=...)`` returning (H, W) (scored on the mosaic)
or (H, W, 3) (scored on linear RGB); or a method name offered by an installed
reconstruction package through the entry-point group
``spikesim.reconstructors`` (:data:`RECONSTRUCTOR_GROUP`; spikejdd offers all
of its methods and pipelines there).  spikesim never imports a reconstruction
package by name, nor torch.
"""

from __future__ import annotations

import numpy as np

import spikesim as ss
from spikesim.analysis.report import AnalysisResult
from spikesim.analysis.sweep import check_sensor
from spikesim.cfa import mosaic
from spikesim.errors import SpikeSimTypeError, SpikeSimValueError, bad_value
from spikesim.estimate import tfi, tfp
from spikesim.noise import PaperNoise, PhysicalNoise

__all__ = ["noise_budget", "noise_sources", "psnr", "make_reconstructor", "RECONSTRUCTOR_GROUP"]

#: Entry-point group of reconstruction packages: each entry point loads a factory
#: ``factory(name) -> fn(spikes, cfa, center, rate=...)`` that raises
#: :class:`~spikesim.errors.SpikeSimValueError` for a name it does not offer.
RECONSTRUCTOR_GROUP = "spikesim.reconstructors"


def noise_sources(noise) -> dict[str, dict]:
    """Active sources of a noise model → the change that switches each off."""
    if isinstance(noise, PaperNoise):
        cand = {"gaussian (sigma_g)": ("sigma_g", 0.0), "poisson (sigma_p)": ("sigma_p", 0.0)}
    elif isinstance(noise, PhysicalNoise):
        cand = {
            "shot noise": ("shot_noise", False),
            "dark current": ("dark_current_rel", 0.0),
            "threshold mismatch": ("threshold_mismatch", 0.0),
            "PRNU": ("prnu", 0.0),
            "temporal threshold noise": ("temporal_threshold_noise", 0.0),
            "hot pixels": ("hot_pixel_fraction", 0.0),
        }
    else:
        return {}
    out = {}
    for name, (field, off) in cand.items():
        if getattr(noise, field) != off:
            if field == "hot_pixel_fraction" and noise.hot_pixel_dark_rel == 0:
                continue
            out[name] = {field: off}
    return out


def psnr(x: np.ndarray, ref: np.ndarray) -> float:
    """PSNR in dB, peak 1.0, both clamped to [0, 1] (docs/architecture.md, Conventions)."""
    mse = float(np.mean((np.clip(x, 0, 1) - np.clip(ref, 0, 1)) ** 2))
    return 10 * np.log10(1.0 / mse) if mse > 0 else np.inf


def make_reconstructor(method="tfp", window: int = 41):
    """``fn(spikes, cfa, center, rate)`` for a method name or callable (see module notes)."""
    if callable(method):
        return _rate_if_declared(method), getattr(method, "__name__", "callable")
    if method == "tfp":
        return (lambda s, cfa, c, rate: tfp(s, c, window, rate)), f"tfp (w={window})"
    if method == "tfi":
        return (lambda s, cfa, c, rate: tfi(s, c, rate)), "tfi"
    if not isinstance(method, str):
        raise SpikeSimTypeError(f"method must be a name or a callable, got {type(method).__name__}")
    from importlib.metadata import entry_points

    refusals = []
    for ep in entry_points(group=RECONSTRUCTOR_GROUP):
        try:
            return ep.load()(method), method
        except SpikeSimValueError as exc:
            refusals.append(f"{ep.name}: {exc}")
    if not refusals:
        raise bad_value("method", method, "'tfp', 'tfi' or a callable (no reconstruction "
                        f"package offers methods through {RECONSTRUCTOR_GROUP!r}; installing "
                        "spikejdd adds its methods)")
    raise bad_value("method", method, "'tfp', 'tfi', a callable, or a method an installed "
                    "reconstruction package offers (" + "; ".join(refusals) + ")")


def _rate_if_declared(fn):
    """``fn`` called with ``rate`` only when it declares it (or ``**kwargs``), as
    spikejdd's method protocol does: ``fn(spikes, cfa, center)`` works too."""
    import inspect

    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):  # no signature to read (a builtin): pass rate
        return fn
    if any(p.name == "rate" or p.kind is p.VAR_KEYWORD for p in params):
        return fn
    return lambda s, cfa, c, rate: fn(s, cfa, c)


def _score(stream, clean: bool, fn, centers, sensor):
    spikes = stream.unpack(clean=clean)
    mse = []
    for k, c in enumerate(centers):
        est = np.asarray(fn(spikes, sensor.cfa, int(c), rate=sensor.full_scale_rate))
        gt = stream.gt[k]
        ref = gt if est.ndim == 3 else mosaic(gt, sensor.cfa)
        if est.shape != ref.shape:
            raise bad_value("method output shape", est.shape, f"{ref.shape[:2]} or (H, W, 3)")
        mse.append(np.mean((np.clip(est, 0, 1) - np.clip(ref, 0, 1)) ** 2))
    return float(np.mean(mse))


def noise_budget(scene="astronaut", sensor="physical", n_readouts: int = 400, seed: int = 0,
                 method="tfp", window: int = 41, n_centers: int = 4,
                 size: tuple[int, int] = (64, 64), motion: str | None = None,
                 progress: bool = False) -> AnalysisResult:
    """Attribute the reconstruction error of ``sensor`` on ``scene`` to its noise sources.

    Parameters
    ----------
    scene : scene object or procedural scene name
        A name is built with ``spikesim.scenes.procedural(name, motion, size)``.
    sensor : Sensor or preset name
        Must have a noise model with at least one active source; resized to the scene.
    method : "tfp", "tfi", callable or spikejdd method name
        Reconstruction (see module notes).
    n_centers : int
        Readouts reconstructed, evenly spaced away from the stream ends.
    """
    sensor = check_sensor(sensor)
    if isinstance(scene, str):
        scene = ss.scenes.procedural(scene, motion=motion, size=size)
    sensor = sensor.replace(height=scene.height, width=scene.width)
    sources = noise_sources(sensor.noise)
    if not sources:
        raise bad_value("sensor.noise", sensor.noise.to_dict() if sensor.noise else None,
                        "a noise model with at least one active source")
    if not isinstance(n_centers, int) or n_centers < 1:
        raise bad_value("n_centers", n_centers, "an integer >= 1")
    margin = window // 2 + 1
    if n_readouts < 2 * margin + n_centers:
        raise bad_value("n_readouts", n_readouts, f">= {2 * margin + n_centers} for window "
                        f"{window} and {n_centers} centres")
    centers = np.linspace(margin, n_readouts - margin - 1, n_centers).round().astype(int)
    centers = sorted(set(centers.tolist()))
    fn, label = make_reconstructor(method, window)

    runs = {"all": (sensor, True)}
    for name, change in sources.items():
        runs[f"all − {name}"] = (sensor.replace(noise=sensor.noise.replace(**change)), False)
    mse = {}
    items = list(runs.items())
    if progress:
        from tqdm.auto import tqdm

        items = tqdm(items, desc="budget", unit="run")
    for key, (sen, twin) in items:
        st = ss.simulate(scene, sen, n_readouts, seed=seed, clean_twin=twin, gt_readouts=centers)
        mse[key] = _score(st, False, fn, centers, sen)
        if twin:
            mse["none"] = _score(st, True, fn, centers, sen)
    db = {k: 10 * np.log10(1.0 / v) if v > 0 else np.inf for k, v in mse.items()}
    total_db = db["none"] - db["all"]
    total_mse = mse["all"] - mse["none"]
    costs, rows = {}, []
    for name in sources:
        k = f"all − {name}"
        d_mse = mse["all"] - mse[k]
        costs[name] = {"psnr_without": db[k], "cost_db": db[k] - db["all"], "excess_mse": d_mse,
                       "share": d_mse / total_mse if total_mse else np.nan}
        rows.append((name, db[k], costs[name]["cost_db"], d_mse, costs[name]["share"]))
    interaction = total_mse - sum(c["excess_mse"] for c in costs.values())
    rows.append(("all sources (total)", db["none"], total_db, total_mse, 1.0))
    rows.append(("interaction (total − Σ)", None, None, interaction,
                 interaction / total_mse if total_mse else np.nan))
    data = {"sensor": sensor.to_dict(), "scene": scene.describe(), "n_readouts": n_readouts,
            "seed": seed, "method": label, "centers": centers, "psnr_all": db["all"],
            "psnr_none": db["none"], "total_cost_db": total_db, "total_excess_mse": total_mse,
            "sum_cost_db": sum(c["cost_db"] for c in costs.values()),
            "interaction_mse": interaction, "costs": costs, "mse": mse}
    notes = [
        f"Scene {scene.describe().get('name', type(scene).__name__)!s}, "
        f"{scene.height}×{scene.width}, {n_readouts} readouts, seed {seed}, "
        f"reconstruction {label} at readouts {centers}. PSNR(all) = {db['all']:.2f} dB, "
        f"PSNR(none, clean twin) = {db['none']:.2f} dB.",
        "cost = PSNR(all − source) − PSNR(all). Costs add in excess MSE, not in dB: share = "
        "ΔMSE_s/ΔMSE_total; interaction = ΔMSE_total − Σ ΔMSE_s (0 for independent additive "
        f"noise). Σ cost_dB = {data['sum_cost_db']:.3f} dB against a total of {total_db:.3f} dB.",
    ]

    def plot(fig):
        ax1, ax2 = fig.subplots(1, 2)
        names = list(costs)
        ax1.barh(names + ["total"], [costs[n]["cost_db"] for n in names] + [total_db],
                 color=["C0"] * len(names) + ["C3"])
        ax1.set(xlabel="PSNR cost (dB)", title="cost of each noise source")
        ax1.invert_yaxis()
        ax2.barh(names + ["interaction"],
                 [costs[n]["share"] for n in names] + [interaction / total_mse
                                                        if total_mse else 0.0],
                 color=["C0"] * len(names) + ["C7"])
        ax2.set(xlabel="share of excess MSE", title="additive decomposition")
        ax2.invert_yaxis()

    return AnalysisResult("budget", "Noise budget", data,
                          [("PSNR cost per source", ["source", "PSNR without it (dB)",
                                                     "cost (dB)", "excess MSE", "share"], rows)],
                          notes, plot)
