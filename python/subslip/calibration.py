"""subslip.fit: the law's constants fitted to measured friction curves (`fit: contact`) or to
single-crystal stress-strain curves (`fit: crystal`), as `subslip fit` fits them (the same C++
function), and the report's figure (docs/calibration.md).

    import subslip
    report = subslip.fit("inputs/contact_fit_five_speeds.yaml")
    print(report["estimate"]["eta_v"], report["interval"]["eta_v"])
    subslip.fit_figure(report, "fit.png")

    report = subslip.fit("inputs/crystal_fit_three_orientations.yaml")
    print(report["initial_crss"])   # {"value": ..., "unit": "MPa"}
"""

import json
import os
import warnings

from ._native import core
from .errors import FitWarning


def fit(path):
    """Fits the problem of the FIT.yaml `path` and returns the report `subslip fit PATH --json`
    prints, as a dict: kind ("contact" or "crystal"), estimate, standard_error, interval, unit and
    correlation (each by constant name), warnings, converged, termination, points, residual_sd
    and curves. A contact fit's curves have name, speed, slip, data (f_t/f_n) and fit; a crystal
    fit's have name, orientation (Bunge Euler angles, degrees), strain_rate, strain (ln F11),
    data and fit (sigma11 in the report's stress_unit), and the report gives the initial CRSS at
    the estimate (initial_crss: value and unit). Each warning is also issued as a FitWarning. Bad
    input raises SceneError with the command line's message (file, line, key)."""
    report = json.loads(core().fit_report(os.fspath(path)))
    for w in report["warnings"]:
        warnings.warn(w, FitWarning, stacklevel=2)
    return report


def fit_figure(report, path):
    """Draws the report's curves into `path` (.png or .pdf, by its suffix): measured (points) and
    fitted (line), and below them the residuals: f_t/f_n against the sliding distance for every
    curve of a contact fit, the axial stress against the axial strain for every orientation of a
    crystal fit. Needs matplotlib (Debian: python3-matplotlib). The file is written whole or not
    at all (drawn beside it, then renamed)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 7), sharex=True,
                                      gridspec_kw={"height_ratios": [3, 1]})
    if report.get("kind") == "crystal":
        _draw_crystal(report, top, bottom)
    else:
        _draw_contact(report, top, bottom)
    status = "converged" if report["converged"] else "NOT converged"
    top.set_title(f"{os.path.basename(report['file'])}: fit {status}, "
                  f"residual s.d. {report['residual_sd']:.3g}", fontsize="medium")
    bottom.axhline(0.0, color="k", lw=0.5)
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


def _draw_curves(curves, x_key, labels, top, bottom):
    for k, (curve, label) in enumerate(zip(curves, labels)):
        colour = f"C{k % 10}"
        top.plot(curve[x_key], curve["data"], "o", ms=3, color=colour, alpha=0.6)
        top.plot(curve[x_key], curve["fit"], "-", color=colour, label=label)
        residual = [f - d for f, d in zip(curve["fit"], curve["data"])]
        bottom.plot(curve[x_key], residual, "o", ms=3, color=colour)


def _draw_contact(report, top, bottom):
    length = report.get("length_unit", "")
    speed_unit = f"{length}/{report.get('time_unit', '')}"
    curves = report["curves"]
    _draw_curves(curves, "slip", [f"{c['speed']:g} {speed_unit}" for c in curves], top, bottom)
    top.set_xscale("log")
    top.set_ylabel("f_t / f_n [-]")
    top.legend(title="sliding speed (points: data, lines: fit)", fontsize="small")
    bottom.set_xlabel(f"sliding distance [{length}]")
    bottom.set_ylabel("fit - data [-]")


def _draw_crystal(report, top, bottom):
    stress = report.get("stress_unit", "")
    rate_unit = f"1/{report.get('time_unit', '')}"
    curves = report["curves"]
    labels = [f"{c['name']}: Euler ({', '.join(f'{a:g}' for a in c['orientation'])}) deg, "
              f"{c['strain_rate']:g} {rate_unit}" for c in curves]
    _draw_curves(curves, "strain", labels, top, bottom)
    top.set_ylabel(f"axial stress sigma11 [{stress}]")
    crss = report.get("initial_crss")
    title = "orientation, strain rate (points: data, lines: fit)"
    if crss:
        title += f"\ninitial CRSS at the estimate {crss['value']:.4g} {crss['unit']}"
    top.legend(title=title, fontsize="small", title_fontsize="small")
    bottom.set_xlabel("axial strain ln F11 [-]")
    bottom.set_ylabel(f"fit - data [{stress}]")
