"""The goodness-of-fit report of a calibration: calibrated and default re-simulations side by side.

:func:`spikesim.analysis.fitcheck.compare_resimulations` re-simulates the
capture with the calibrated sensor and with the package defaults; this module
turns the result into the report's tables (Markdown and JSON rows) and its
figure (three panels, matplotlib):

1. the per-pixel rate distribution (empirical CDF) of the capture and of both
   re-simulations over the largest flat region (or pool), with the rate KS
   distance of each;
2. the interval CV per rate bin (octaves of mean interval) of the capture and
   of both re-simulations;
3. the spatial spread (relative s.d. of the rates) of each flat region (or
   pool) in the capture and in both re-simulations.

The distances are those of :mod:`spikesim.analysis.gof_stats`; 0 is identical,
smaller is closer.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DISTANCES", "comparison_rows", "cv_rows", "spread_rows", "plot_comparison",
           "verdict"]

#: (summary key, name in the tables) of the three distances.
DISTANCES = (("rate_ks", "rate KS (mean D)"), ("interval_cv_error", "interval CV error"),
             ("spatial_spread_error", "spatial spread error"))


def comparison_rows(fits: dict, ties: dict | None = None) -> tuple[list, list]:
    """``(headers, rows)``: one row per distance, the calibrated and default values
    and which is closer; ``ties`` maps a distance's key to why the two sensors
    share what it measures most (a part of the model the capture did not
    identify, kept at the package defaults in both), said after the verdict."""
    cal, dft = fits["calibrated"]["summary"], fits["defaults"]["summary"]
    rows = []
    for key, name in DISTANCES:
        c, d = cal[key], dft[key]
        if np.isfinite(c) and np.isfinite(d):
            closer = "calibrated" if c <= d else "defaults"
        else:
            closer = "not measured"
        if ties and key in ties and closer != "not measured":
            closer += f" ({ties[key]})"
        rows.append((name, c, d, closer))
    return ["distance from the capture", "calibrated", "defaults", "closer"], rows


def cv_rows(fits: dict) -> tuple[list, list]:
    """``(headers, rows)``: the interval CV per mean-interval bin of the capture and
    of both re-simulations."""
    cal = {(b["lo"], b["hi"]): b for b in fits["calibrated"]["summary"]["cv_bins"]}
    dft = {(b["lo"], b["hi"]): b for b in fits["defaults"]["summary"]["cv_bins"]}
    rows = []
    for key in sorted(set(cal) | set(dft)):
        c, d = cal.get(key), dft.get(key)
        ref = c or d
        rows.append((f"{key[0]:g}-{key[1]:g}", ref["capture_pixels"], ref["capture_cv"],
                     c["resim_cv"] if c else float("nan"), d["resim_cv"] if d else float("nan")))
    return ["mean interval (readouts)", "capture pixels", "capture CV", "calibrated CV",
            "defaults CV"], rows


def spread_rows(fits: dict, names=None) -> tuple[list, list]:
    """``(headers, rows)``: the spatial spread of each flat region (or pool) in the
    capture and in both re-simulations; ``names`` label the flat regions."""
    cal = fits["calibrated"]["summary"]["spatial_spread"]
    dft = fits["defaults"]["summary"]["spatial_spread"]
    rows = []
    for i, (c, d) in enumerate(zip(cal, dft, strict=True)):
        if "pool" in c:
            label = f"pool {c['pool']} (~{c['rate']:.3g} spikes/readout, {c['pixels']} px)"
        else:
            label = names[i] if names and i < len(names) else f"flat region {i}"
        rows.append((label, c["capture"], c["resim"], d["resim"]))
    return ["region", "capture spread", "calibrated spread", "defaults spread"], rows


def verdict(fits: dict, ties: dict | None = None) -> str:
    """One sentence: which re-simulation is closer on each distance."""
    _, rows = comparison_rows(fits, ties)
    parts = []
    for name, c, d, closer in rows:
        short = name.split(" (")[0].replace(" error", "")
        if closer == "not measured":
            parts.append(f"{short}: not measured")
        else:
            who = closer.split(" (")[0]
            parts.append(f"{short}: {who} closer ({c:.3g} vs {d:.3g}){closer[len(who):]}")
    return "Re-simulation against the capture, calibrated vs package defaults — " + \
        "; ".join(parts) + "."


def plot_comparison(fits: dict):
    """A function drawing the three panels (module notes) on a matplotlib figure."""

    def draw(fig):
        ax1, ax2, ax3 = fig.subplots(1, 3)
        cap_rates, _ = fits["calibrated"]["curves"]["rates"]
        styles = {"capture": ("k", "-"), "calibrated": ("C0", "--"), "defaults": ("C3", ":")}
        curves = {"capture": cap_rates, **{k: fits[k]["curves"]["rates"][1]
                                           for k in ("calibrated", "defaults")}}
        for name, vals in curves.items():
            v = np.sort(np.asarray(vals, np.float64))
            if v.size:
                color, ls = styles[name]
                d = fits[name]["summary"]["rate_ks"] if name != "capture" else None
                label = name if d is None else f"{name} (KS {d:.3g})"
                ax1.plot(v, np.linspace(0, 1, v.size), ls, color=color, label=label)
        ax1.set(xlabel=fits["calibrated"]["curves"]["rate_label"], ylabel="CDF",
                title="per-pixel rates")
        ax1.legend(fontsize=7)
        _, rows = cv_rows(fits)
        if rows:
            mid = [np.sqrt(float(a) * float(b)) for a, b in (r[0].split("-") for r in rows)]
            for col, name in ((2, "capture"), (3, "calibrated"), (4, "defaults")):
                color, ls = styles[name]
                ax2.plot(mid, [r[col] for r in rows], ls, marker="o", color=color, label=name)
            ax2.set_xscale("log")
        ax2.set(xlabel="mean interval (readouts)", ylabel="interval CV",
                title="interval CV per rate bin")
        ax2.legend(fontsize=7)
        _, rows = spread_rows(fits)
        x = np.arange(len(rows))
        for k, (col, name) in enumerate(((1, "capture"), (2, "calibrated"), (3, "defaults"))):
            color, _ = styles[name]
            ax3.bar(x + (k - 1) * 0.27, [r[col] for r in rows], 0.27, color=color, label=name)
        ax3.set(xticks=x, xticklabels=[str(i) for i in x], xlabel="flat region / pool",
                ylabel="relative s.d. of rates", title="spatial spread")
        ax3.legend(fontsize=7)

    return draw
