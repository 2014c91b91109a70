"""subslip.fit: the law's constants fitted to measured friction curves, as `subslip fit` fits
them (the same C++ function), and the report's figure (docs/calibration.md).

    import subslip
    report = subslip.fit("inputs/contact_fit_five_speeds.yaml")
    print(report["estimate"]["eta_v"], report["interval"]["eta_v"])
    subslip.fit_figure(report, "fit.png")
"""

import json
import os
import warnings

from ._native import core
from .errors import FitWarning


def fit(path):
    """Fits the problem of the FIT.yaml `path` and returns the report `subslip fit PATH --json`
    prints, as a dict: estimate, standard_error, interval, unit and correlation (each by constant
    name), warnings, converged, termination, points, residual_sd and curves (each with name,
    speed, slip, data and fit). Each warning is also issued as a FitWarning. Bad input raises
    SceneError with the command line's message (file, line, key)."""
    report = json.loads(core().fit_report(os.fspath(path)))
    for w in report["warnings"]:
        warnings.warn(w, FitWarning, stacklevel=2)
    return report


def fit_figure(report, path):
    """Draws the report's curves into `path` (.png or .pdf, by its suffix): f_t/f_n measured
    (points) and fitted (line) against the sliding distance for every curve, and below them the
    residuals. Needs matplotlib (Debian: python3-matplotlib). The file is written whole or not
    at all (drawn beside it, then renamed)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    length = report.get("length_unit", "")
    speed_unit = f"{length}/{report.get('time_unit', '')}"
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 7), sharex=True,
                                      gridspec_kw={"height_ratios": [3, 1]})
    for k, curve in enumerate(report["curves"]):
        colour = f"C{k % 10}"
        label = f"{curve['speed']:g} {speed_unit}"
        top.plot(curve["slip"], curve["data"], "o", ms=3, color=colour, alpha=0.6)
        top.plot(curve["slip"], curve["fit"], "-", color=colour, label=label)
        residual = [f - d for f, d in zip(curve["fit"], curve["data"])]
        bottom.plot(curve["slip"], residual, "o", ms=3, color=colour)
    top.set_xscale("log")
    top.set_ylabel("f_t / f_n [-]")
    top.legend(title="sliding speed (points: data, lines: fit)", fontsize="small")
    status = "converged" if report["converged"] else "NOT converged"
    top.set_title(f"{os.path.basename(report['file'])}: fit {status}, "
                  f"residual s.d. {report['residual_sd']:.3g}", fontsize="medium")
    bottom.axhline(0.0, color="k", lw=0.5)
    bottom.set_xlabel(f"sliding distance [{length}]")
    bottom.set_ylabel("fit - data [-]")
    fig.tight_layout()
    root, suffix = os.path.splitext(os.fspath(path))
    partial = root + ".partial" + suffix
    try:
        fig.savefig(partial)
        os.replace(partial, path)
    finally:
        plt.close(fig)
        if os.path.exists(partial):
            os.remove(partial)
