#!/usr/bin/python3
"""The standard pictures of a subslip result file (docs/scenes.md), as PNG, PDF or SVG files.

    scripts/subslip_plots.py RESULT.h5 [-o DIR] [--case NAME] [--component IJ]
                             [--format png,pdf,svg] [--dpi DPI] [--docs-size]

Draws what the file has data for and says what it skips (names for --format png):
  stress_strain.png          crystal: the loading component sigma_ij against eps_ij and the von
                             Mises stress against the von Mises strain, one curve per case; with
                             a peak at the start, sigma_ij against |eps_ij| on a logarithmic
                             axis; with holds (the loading strain still while time runs), sigma_ij
                             against time, holds shaded
  traction_ratio.png         contact: f_t/f_n against the sliding distance (linear and
                             logarithmic: the friction peak sits at the start), one curve per
                             case; with holds (no sliding while time runs), f_t/f_n and mu
                             against time, holds shaded
  slip_activity_<case>.png   crystal with grain fields slip_rate and/or slip: the grain average
                             (weighted) of |slip rate| and of |accumulated slip| per slip system
                             against the loading strain
  pole_figures_<case>.png    crystal with grain orientations: {111} {100} {110} pole figures
                             ({0001} {10-10} {11-20} for hcp) of the initial and final texture,
                             pole density contours in multiples of a random distribution

Every picture is written as a 300 dpi PNG and a PDF (--format: any of png, pdf, svg; --dpi);
--docs-size writes small PNGs for documentation pages (100 dpi).

Axes follow the loading: a case loaded in compression (its loading strain component negative)
is drawn as positive magnitudes, -eps_ij and -sigma_ij, and the axes say so ("compressive").

Pole figures: sample frame x = RD (right), y = TD (up), z = ND (towards the viewer), the axes of
rolling and plane-strain compression (for other loadings read them as x, y, z); upper
hemisphere, equal-area (Lambert) projection scaled to the unit circle. The file stores each
orientation as the quaternion of g with v_crystal = g v_sample (passive, Rowenhorst et al. 2015,
P = -1), so a crystal direction c points along g^T c in the sample. The density is a sum of von
Mises-Fisher kernels on the sphere (subslip.texture.pole_density), weighted by grains/weight.

A hold is an interval in which the abscissa of a panel (sliding distance, loading strain) does
not change while time runs: on that abscissa it is a vertical line, so a time panel is added
when holds take at least 1 % of a case's time (HOLD_FRACTION). Axis labels state units, legends
name each case by its swept values with their units (speed=200 mm/min). The file is
read with the package python/subslip (docs/python.md). Needs Debian's python3-h5py,
python3-numpy and python3-matplotlib; run with /usr/bin/python3.
"""

import argparse
import math
import os
import re
import sys

# The package python/subslip reads the file (valid rows, tensors, derived quantities).
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                "python"))
try:
    import subslip  # MissingDependency (an ImportError) names the package to install
    from subslip._deps import require

    np = require("numpy", "subslip_plots.py")
    matplotlib = require("matplotlib", "subslip_plots.py")
except ImportError as missing:
    print(f"subslip_plots: error: {missing}", file=sys.stderr)
    sys.exit(2)

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)

from subslip.derived import weighted_mean_abs  # noqa: E402
from subslip.texture import pole_density, pole_families, pole_figure_points  # noqa: E402

# The geometry and reading this script draws with, as scripts/test_subslip_plots.py checks them
# through this module.
from subslip.texture import (cubic_family, hexagonal_family, quaternion_to_matrix,  # noqa: E402
                             sample_directions, upper_hemisphere_projection)

Result = subslip.Result
__all__ = ["main", "Result", "cubic_family", "hexagonal_family", "quaternion_to_matrix",
           "sample_directions", "upper_hemisphere_projection", "pole_figure_points",
           "hold_intervals", "holds_matter", "peak_at_start", "loading_sign", "pole_density"]
FORMATS = ("png", "pdf", "svg")


def message(text):
    print("subslip_plots: " + text, file=sys.stderr)


def file_safe(name):
    """The file-name form `subslip post` uses: letters, digits and ._=+- kept, others '_'."""
    return re.sub(r"[^A-Za-z0-9._=+-]", "_", name)


def heading(result, what=""):
    """`what: title`, marked when the run did not complete."""
    note = "" if result.completed else " (INCOMPLETE run)"
    parts = [p for p in (what, result.title) if p]
    return ": ".join(parts) + note


# ---------------------------------------------------------------- pictures


# A talk's resolution, and the documentation's (PNG files of docs/ stay small).
TALK_DPI = 300.0
DOCS_DPI = 100.0


class Output:
    """Where and how pictures are saved: directory, formats (png, pdf, svg), resolution."""

    def __init__(self, directory, formats=("png",), dpi=TALK_DPI):
        self.directory, self.formats, self.dpi = directory, tuple(formats), dpi

    def save(self, fig, stem):
        """Saves `fig` in every format; returns the first path."""
        paths = []
        for fmt in self.formats:
            path = os.path.join(self.directory, f"{stem}.{fmt}")
            # PDF and SVG are vector graphics; only their embedded images (contours) take dpi.
            fig.savefig(path, dpi=self.dpi)
            print(path)
            paths.append(path)
        plt.close(fig)
        return paths[0]


def legend(ax, count):
    if count > 1:
        ax.legend(fontsize="small" if count <= 8 else "x-small", ncol=1 if count <= 10 else 2,
                  loc="best")


def loading_sign(strain_component):
    """-1 for a case loaded in compression (its loading strain component is largest where it
    is negative), else +1: the sign that draws the loading as positive magnitudes."""
    e = np.asarray(strain_component, dtype=float)
    e = e[np.isfinite(e)]
    if len(e) == 0:
        return 1.0
    return -1.0 if e[np.argmax(np.abs(e))] < 0.0 else 1.0


def signed_label(symbol, ij, signs):
    """An axis label for the loading component drawn with `signs` (one per case)."""
    if all(s < 0 for s in signs):
        return f"compressive {symbol[0]} $-\\{symbol[1]}_{{{ij}}}$"
    if any(s < 0 for s in signs):
        return f"{symbol[0]} $\\pm\\{symbol[1]}_{{{ij}}}$ (compression positive)"
    return f"{symbol[0]} $\\{symbol[1]}_{{{ij}}}$"


def largest_component(tensor):
    """(i, j) of the largest absolute component of a 3x3 tensor."""
    return divmod(int(np.argmax(np.abs(tensor))), 3)


# Holds taking at least this fraction of a case's time get a time panel.
HOLD_FRACTION = 0.01
# A peak "at the start": the largest |value| is reached within this fraction of the abscissa's
# range, and the last value is at least PEAK_DROP below it (relative).
PEAK_WITHIN = 0.25
PEAK_DROP = 0.01


def hold_intervals(time, x):
    """[(t0, t1)] of the intervals in which `x` does not change while time runs (merged), for
    series of the same length. `x` counts as unchanged within 1e-12 of its largest |value|."""
    time, x = np.asarray(time, float), np.asarray(x, float)
    if len(time) < 2:
        return []
    scale = np.max(np.abs(x)) if np.all(np.isfinite(x)) else 0.0
    still = (np.abs(np.diff(x)) <= 1e-12 * scale) & (np.diff(time) > 0)
    intervals = []
    for k in np.flatnonzero(still):
        t0, t1 = time[k], time[k + 1]
        if intervals and intervals[-1][1] == t0:
            intervals[-1] = (intervals[-1][0], t1)
        else:
            intervals.append((t0, t1))
    return intervals


def holds_matter(time, x):
    """Whether the holds of (time, x) take at least HOLD_FRACTION of the time."""
    intervals = hold_intervals(time, x)
    total = float(time[-1] - time[0]) if len(time) > 1 else 0.0
    return total > 0 and sum(t1 - t0 for t0, t1 in intervals) >= HOLD_FRACTION * total


def peak_at_start(x, y):
    """Whether |y| peaks within the first PEAK_WITHIN of the range of |x| and then falls by at
    least PEAK_DROP (the friction peak; a yield point)."""
    x, y = np.abs(np.asarray(x, float)), np.abs(np.asarray(y, float))
    if len(x) < 3 or not np.all(np.isfinite(y)) or np.max(x) <= np.min(x):
        return False
    k = int(np.argmax(y))
    early = x[k] - np.min(x) <= PEAK_WITHIN * (np.max(x) - np.min(x))
    return bool(early and y[-1] < (1.0 - PEAK_DROP) * y[k])


def shade_holds(ax, intervals):
    """Light grey bands over hold intervals, one legend entry ("hold")."""
    for k, (t0, t1) in enumerate(intervals):
        ax.axvspan(t0, t1, color="0.9", zorder=0, label="hold" if k == 0 else "_nolegend_")


def plot_stress_strain(result, cases, output, component=None):
    if result.scene_kind != "crystal":
        message("stress-strain: not a crystal result, skipped")
        return None
    usable = [c for c in cases
              if "macro/stress" in result.case(c) and "macro/strain" in result.case(c)]
    if not usable:
        message("stress-strain: no macro/stress and macro/strain in the file, skipped")
        return None
    stress_unit = result.units.get("stress", "")
    time_unit = result.units.get("time", "")
    curves = []  # (case, i, j, stress, strain, time), compression drawn as positive magnitudes
    signs = []
    for name in usable:
        case = result.case(name)
        stress, strain = case.series("macro/stress"), case.series("macro/strain")  # (n, 3, 3)
        i, j = component or case.loading_component() or largest_component(strain[-1])
        time = case.time() if "macro/time" in case else None
        sign = loading_sign(strain[:, i, j])
        signs.append(sign)
        curves.append((case, i, j, sign * stress, sign * strain, time))
    log_panel = any(peak_at_start(e[:, i, j], s[:, i, j]) for _, i, j, s, e, _ in curves)
    time_panel = any(t is not None and holds_matter(t, e[:, i, j])
                     for _, i, j, _, e, t in curves)
    panels = 2 + log_panel + time_panel
    fig, axes = plt.subplots(1, panels, figsize=(5 * panels, 4.2), squeeze=False)
    ax1, ax2 = axes[0][0], axes[0][1]
    ax_log = axes[0][2] if log_panel else None
    ax_time = axes[0][-1] if time_panel else None
    components = set()
    for k, (case, i, j, stress, strain, time) in enumerate(curves):
        label_ij = f"{i + 1}{j + 1}"
        components.add(label_ij)
        colour = f"C{k % 10}"
        ax1.plot(strain[:, i, j], stress[:, i, j], color=colour,
                 label=f"{case.label()} ({label_ij}{', compression' if signs[k] < 0 else ''})")
        ax2.plot(case.von_mises_strain(), case.von_mises_stress(), color=colour,
                 label=case.label())
        if ax_log is not None:
            e = np.abs(strain[:, i, j])
            ax_log.plot(e[e > 0], stress[e > 0, i, j], color=colour, label=case.label())
        if ax_time is not None and time is not None:
            ax_time.plot(time, stress[:, i, j], color=colour, label=case.label())
            if k == 0:
                shade_holds(ax_time, hold_intervals(time, strain[:, i, j]))
    ij = components.pop() if len(components) == 1 else "ij"
    strain_label = signed_label(("strain", "varepsilon"), ij, signs)
    stress_label = signed_label(("stress", "sigma"), ij, signs)
    ax1.set_xlabel(f"{strain_label} [1]")
    ax1.set_ylabel(f"{stress_label} [{stress_unit}]")
    ax1.set_title("loading component (largest prescribed $L_{ij}$)")
    ax2.set_xlabel("von Mises strain [1]")
    ax2.set_ylabel(f"von Mises stress [{stress_unit}]")
    ax2.set_title("von Mises")
    if ax_log is not None:
        ax_log.set_xscale("log")
        ax_log.set_xlabel(f"|strain $\\varepsilon_{{{ij}}}$| [1], logarithmic")
        ax_log.set_ylabel(f"{stress_label} [{stress_unit}]")
        ax_log.set_title("the start (peak)")
    if ax_time is not None:
        ax_time.set_xlabel(f"time [{time_unit}]")
        ax_time.set_ylabel(f"{stress_label} [{stress_unit}]")
        ax_time.set_title("against time (holds shaded)")
    drawn = [a for a in (ax1, ax2, ax_log, ax_time) if a is not None]
    for ax in drawn:
        ax.grid(alpha=0.3)
        legend(ax, len(usable) + (ax is ax_time and len(ax.patches) > 0))
    fig.suptitle(heading(result, "stress-strain"), fontsize="medium")
    fig.tight_layout()
    return output.save(fig, "stress_strain")


def sliding_abscissa(result, case):
    """(values, axis label) of the sliding distance, else the displacement u_x, else None."""
    length = result.units.get("length", "")
    if "slip_path" in case:
        return case.series("slip_path"), f"sliding distance [{length}]"
    if "slip" in case:
        return case.series("slip")[:, 0], f"sliding displacement u_x [{length}]"
    return None


def plot_traction_ratio(result, cases, output):
    if result.scene_kind != "contact":
        message("traction ratio: not a contact result, skipped")
        return None
    # Linear (the paper's view) and logarithmic in the distance (the friction peak sits at the
    # start); against time when the cases hold (no sliding while time runs).
    curves = []  # (case, x, ratio)
    xlabel = ""
    for name in cases:
        case = result.case(name)
        abscissa = sliding_abscissa(result, case)
        if "ratio" not in case or abscissa is None:
            continue
        (x, xlabel), ratio = abscissa, case.series("ratio")
        curves.append((case, x, ratio))
    if not curves:
        message("traction ratio: no ratio with slip_path or slip in the file, skipped")
        return None
    time_panel = any("time" in c and holds_matter(c.time(), x) for c, x, _ in curves)
    panels = 2 + time_panel
    fig, axes = plt.subplots(1, panels, figsize=(5.5 * panels, 4.3), squeeze=False)
    ax, ax_log = axes[0][0], axes[0][1]
    ax_time = axes[0][2] if time_panel else None
    for k, (case, x, ratio) in enumerate(curves):
        colour = f"C{k % 10}"
        ax.plot(x, ratio, color=colour, label=case.label())
        positive = x > 0
        ax_log.plot(x[positive], ratio[positive], color=colour, label=case.label())
        if ax_time is not None and "time" in case:
            time = case.time()
            ax_time.plot(time, ratio, color=colour, label=case.label())
            if "mu" in case:
                ax_time.plot(time, case.series("mu"), color=colour, ls=":", lw=1.2,
                             label="_nolegend_")
            if k == 0:
                shade_holds(ax_time, hold_intervals(time, x))
    ax_log.set_xscale("log")
    for a in (ax, ax_log):
        a.set_xlabel(xlabel)
        a.set_ylabel("traction ratio $f_t/f_n$ [1]")
        a.grid(alpha=0.3)
    ax_log.set_xlabel(xlabel + ", logarithmic")
    drawn = len(curves)
    # The legend where the curves are apart: on the logarithmic panel, whose start (the peak)
    # separates the cases, while on the linear one they crowd into the first millimetre.
    legend(ax_log, drawn)
    if ax_time is not None:
        ax_time.set_xlabel(f"time [{result.units.get('time', '')}]")
        ax_time.set_ylabel("$f_t/f_n$ (solid), friction coefficient $\\mu$ (dotted) [1]")
        ax_time.set_title("against time (holds shaded)")
        ax_time.grid(alpha=0.3)
        legend(ax_time, drawn + (len(ax_time.patches) > 0))
    fig.suptitle(heading(result, "traction ratio"), fontsize="medium")
    fig.tight_layout()
    return output.save(fig, "traction_ratio")


def system_families(case, count):
    """Per slip system: its family and its label without the family, from the `labels` of
    grains/slip_systems ("fcc_111_110 (1 1 1)[1 0 -1]")."""
    labels = case.slip_system_labels() if "grains/slip_systems" in case else []
    if len(labels) != count:
        return [""] * count, [f"system {a}" for a in range(count)]
    families, short = [], []
    for label in labels:
        head, _, rest = label.partition(" ")
        named = rest and not head.startswith(("(", "["))
        families.append(head if named else "")
        short.append(rest if named else label)
    return families, short


def loading_strain(result, case):
    """The abscissa for grain fields: the loading strain component, else time."""
    ij = case.loading_component()
    rows = case.grain_rows()  # the output rows that have grain fields (output.grains_at)
    if "macro/strain" in case and ij is not None:
        strain = case.series("macro/strain")[:, ij[0], ij[1]]
        sign = loading_sign(strain)
        symbol = signed_label(("strain", "varepsilon"), f"{ij[0] + 1}{ij[1] + 1}", [sign])
        return sign * strain[rows], f"{symbol} [1]"
    return case.time()[rows], f"time [{result.units.get('time', '')}]"


def system_mean(case, field):
    """Grain-weighted mean |value| per slip system (n, N) of grains/slip_rate or grains/slip."""
    if field == "slip_rate":
        return case.slip_activity()
    return weighted_mean_abs(case.series(f"grains/{field}"), case.grain_weights())


def plot_slip_activity(result, name, output):
    case = result.case(name)
    fields = [f for f in ("slip_rate", "slip") if f"grains/{f}" in case]
    if result.scene_kind != "crystal" or not fields or "macro/time" not in case:
        message(f"slip activity ({name}): no grains/slip_rate or grains/slip in the file, skipped")
        return None
    x, xlabel = loading_strain(result, case)
    count = case.dataset(f"grains/{fields[0]}").shape[2]
    families, labels = system_families(case, count)
    distinct = list(dict.fromkeys(families))
    # Up to 12 systems: one colour and legend entry each. More: one colour per family.
    per_system = count <= 12
    if per_system:
        colours = [plt.get_cmap("tab20")(a) for a in range(count)]
        legend_labels = labels
    else:
        colours = [plt.get_cmap("tab10")(distinct.index(f) % 10) for f in families]
        legend_labels = [f if families.index(f) == a else "_nolegend_"
                         for a, f in enumerate(families)]
    legend_width = 2.6
    width = 5.6 * len(fields) + legend_width
    fig, axes = plt.subplots(1, len(fields), figsize=(width, 4.6), squeeze=False)
    for ax, field in zip(axes[0], fields):
        mean = system_mean(case, field)
        for a in range(count):
            ax.plot(x, mean[:, a], color=colours[a], label=legend_labels[a], lw=1.2)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"mean |slip rate| [{case.unit('grains/slip_rate')}]"
                      if field == "slip_rate" else "mean |accumulated slip| [1]")
        ax.grid(alpha=0.3)
    handles, names = axes[0][0].get_legend_handles_labels()
    right = 1.0 - legend_width / width
    fig.legend(handles, names, loc="center left", bbox_to_anchor=(right, 0.5),
               fontsize="x-small", title=distinct[0] if per_system and len(distinct) == 1 else None,
               title_fontsize="x-small", frameon=False)
    fig.suptitle(f"slip activity per slip system (weighted grain average), case {name}\n"
                 + heading(result), fontsize="medium")
    fig.tight_layout(rect=(0, 0, right, 1))
    return output.save(fig, f"slip_activity_{file_safe(name)}")


# Kernel half-width of the pole density: wide enough that a few hundred grains give a smooth
# density, narrow enough to resolve a rolling texture's components.
def density_half_width(grains):
    return 15.0 if grains < 500 else 10.0


# Steps between density contour levels [MRD]: the finest that gives at most MAX_LEVELS levels.
MRD_STEPS = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0)
MAX_LEVELS = 12


def mrd_levels(largest):
    """Contour levels from 0 in even steps up to the first at or above `largest` (1 MRD, a
    random texture's density, is always a level)."""
    step = next((s for s in MRD_STEPS if largest / s <= MAX_LEVELS), MRD_STEPS[-1])
    return list(np.arange(0.0, math.ceil(largest / step) * step + 0.5 * step, step))


def draw_sample_axes(ax):
    """The unit circle, the RD and TD diameters and their labels; ND is the centre."""
    ax.add_patch(plt.Circle((0, 0), 1.0, fill=False, lw=1.0, color="k", zorder=3))
    ax.plot([-1, 1], [0, 0], color="0.6", lw=0.5, zorder=2)
    ax.plot([0, 0], [-1, 1], color="0.6", lw=0.5, zorder=2)
    ax.plot([0], [0], marker="+", color="k", ms=6, zorder=3)
    ax.text(1.05, 0.0, "RD", ha="left", va="center", fontsize="small")
    ax.text(0.0, 1.05, "TD", ha="center", va="bottom", fontsize="small")
    ax.text(0.06, -0.06, "ND", ha="left", va="top", fontsize="x-small")
    ax.set_xlim(-1.2, 1.2)
    ax.set_ylim(-1.2, 1.2)
    ax.set_aspect("equal")
    ax.axis("off")


def draw_pole_figure(ax, density, levels, points=None, marker_size=1.0):
    """Filled density contours (X, Y, mrd) at `levels`, the sample axes, and the poles
    themselves when `points` (X, Y) are given. Returns the contour set (for a colour bar)."""
    X, Y, mrd = density
    filled = ax.contourf(X, Y, mrd, levels=levels, cmap="YlOrRd", zorder=1)
    ax.contour(X, Y, mrd, levels=[1.0], colors="0.35", linewidths=0.6, zorder=2)
    if points is not None:
        ax.scatter(*points, s=marker_size, c="k", alpha=0.5, linewidths=0, zorder=2)
    draw_sample_axes(ax)
    return filled


def textures(result, case):
    """[(label, quaternions)] of the initial and, when the file has it, the final texture."""
    if "grains/orientation" not in case and "grains/initial_orientation" not in case:
        return []
    out = [("initial", case.orientations(0))]
    if "grains/orientation" in case and len(case.series("grains/orientation")) > 1:
        final_time = case.time()[-1]
        out.append((f"final (t = {final_time:.4g} {result.units.get('time', '')})",
                    case.orientations(-1)))
    return out


def plot_pole_figures(result, name, output):
    case = result.case(name)
    drawn = textures(result, case) if result.scene_kind == "crystal" else []
    if not drawn:
        message(f"pole figures ({name}): no grain orientations in the file, skipped")
        return None
    lattice = case.lattice()
    if lattice == "unknown":
        message(f"pole figures ({name}): custom slip systems, lattice unknown; drawing cubic poles")
    families = pole_families(lattice)
    grains = drawn[0][1].shape[0]
    weights = case.grain_weights() if "grains/weight" in case else None
    half_width = density_half_width(grains)
    densities = [[pole_density(q, vectors, weights, half_width) for _, vectors in families]
                 for _, q in drawn]
    largest = max(np.nanmax(d[2]) for row in densities for d in row)
    levels = mrd_levels(largest)
    # The poles themselves only where they do not hide the contours.
    marker = float(np.clip(3000.0 / (grains * len(families[0][1])), 0.5, 20.0))
    show_points = grains <= 300
    fig, axes = plt.subplots(len(drawn), 3, figsize=(9.6, 3.0 * len(drawn) + 0.6),
                             squeeze=False, layout="constrained")
    for row, (label, q) in enumerate(drawn):
        for col, (family, vectors) in enumerate(families):
            ax = axes[row][col]
            points = pole_figure_points(q, vectors) if show_points else None
            filled = draw_pole_figure(ax, densities[row][col], levels, points, marker)
            ax.set_title(f"{family}, {label}", fontsize="medium")
    bar = fig.colorbar(filled, ax=axes.ravel().tolist(), shrink=0.85)
    bar.set_label("pole density [MRD, multiples of random]")
    grain_text = f"{grains} grain{'s' if grains != 1 else ''}"
    frame = (f"x = RD, y = TD, z = ND towards the viewer; upper hemisphere, equal area; "
             f"density: {half_width:g} deg kernel half-width, grey line 1 MRD")
    fig.suptitle(f"{heading(result, f'pole figures, case {name}')}\n{grain_text}; "
                 f"{frame}", fontsize="small")
    return output.save(fig, f"pole_figures_{file_safe(name)}")


def parse_component(text_ij):
    if not re.fullmatch(r"[123][123]", text_ij):
        raise argparse.ArgumentTypeError("give two digits 1-3, e.g. 33 or 12")
    return int(text_ij[0]) - 1, int(text_ij[1]) - 1


def formats(text):
    chosen = tuple(dict.fromkeys(f.strip().lower() for f in text.split(",") if f.strip()))
    unknown = [f for f in chosen if f not in FORMATS]
    if not chosen or unknown:
        raise argparse.ArgumentTypeError(f"'{text}': give png, pdf and/or svg, comma-separated")
    return chosen


def positive(text):
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError("must be > 0")
    return value


def open_result(parser, path):
    if not os.path.isfile(path):
        parser.exit(2, f"subslip_plots: error: {path}: no such file\n")
    try:
        return subslip.open(path)
    except OSError as e:
        parser.exit(2, f"subslip_plots: error: {path}: not readable as HDF5 ({e})\n")
    except subslip.NotAResult as e:
        parser.exit(2, f"subslip_plots: error: {e}\n")


def draw_all(result, cases, output, component):
    """Every picture the file has data for; the paths written (None for those skipped)."""
    written = [plot_stress_strain(result, cases, output, component),
               plot_traction_ratio(result, cases, output)]
    if result.scene_kind == "crystal":
        for name in cases:
            written.append(plot_slip_activity(result, name, output))
            written.append(plot_pole_figures(result, name, output))
    return written


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("result", help="a subslip result file (HDF5)")
    parser.add_argument("-o", "--output", help="directory for the pictures "
                        "(default: RESULT without .h5, plus _plots)")
    parser.add_argument("--case", help="only this case (default: every case)")
    parser.add_argument("--component", type=parse_component,
                        help="stress-strain component ij (default: the largest prescribed L_ij)")
    parser.add_argument("--format", type=formats, default=("png", "pdf"),
                        help="picture formats, comma-separated: png, pdf, svg (default: png,pdf; "
                        "pdf and svg are vector graphics)")
    parser.add_argument("--dpi", type=positive, default=None,
                        help=f"resolution of png pictures in dots per inch (default: "
                        f"{TALK_DPI:g}, with --docs-size {DOCS_DPI:g})")
    parser.add_argument("--docs-size", action="store_true",
                        help=f"small PNG files for documentation pages: png only, "
                        f"{DOCS_DPI:g} dpi unless --dpi")
    args = parser.parse_args(argv)
    result = open_result(parser, args.result)
    cases = result.cases
    if args.case is not None:
        if args.case not in cases:
            parser.exit(2, f"subslip_plots: error: {args.result}: no case '{args.case}'; "
                        f"the file has: {', '.join(cases)}\n")
        cases = [args.case]
    out_dir = args.output or os.path.splitext(args.result)[0] + "_plots"
    os.makedirs(out_dir, exist_ok=True)
    dpi = args.dpi or (DOCS_DPI if args.docs_size else TALK_DPI)
    output = Output(out_dir, ("png",) if args.docs_size else args.format, dpi)
    try:
        written = draw_all(result, cases, output, args.component)
    except subslip.MissingCore as e:  # the von Mises and slip measures are the core's
        parser.exit(2, f"subslip_plots: error: {e}\n")
    count = sum(p is not None for p in written)
    message(f"{count} picture{'s' if count != 1 else ''} in {out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
