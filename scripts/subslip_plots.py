#!/usr/bin/python3
"""The standard pictures of a subslip result file (docs/scenes.md), as PNG, PDF or SVG files.

    scripts/subslip_plots.py RESULT.h5 [-o DIR] [--case NAME] [--component IJ]
                             [--format png|pdf|svg] [--dpi DPI]

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
                             ({0001} {10-10} {11-20} for hcp) of the initial and final texture

Pole figures: sample frame (x right, y up, z towards the viewer), upper hemisphere, equal-area
(Lambert) projection scaled to the unit circle. The file stores each orientation as the
quaternion of g with v_crystal = g v_sample (passive, Rowenhorst et al. 2015, P = -1), so a
crystal direction c points along g^T c in the sample.

A hold is an interval in which the abscissa of a panel (sliding distance, loading strain) does
not change while time runs: on that abscissa it is a vertical line, so a time panel is added
when holds take at least 1 % of a case's time (HOLD_FRACTION). Axis labels state units, legends
name each case by its swept values with their units (speed=200 mm/min). The file is
read with the package python/subslip (docs/python.md). Needs Debian's python3-h5py,
python3-numpy and python3-matplotlib; run with /usr/bin/python3.
"""

import argparse
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
from subslip.texture import pole_families, pole_figure_points  # noqa: E402

# The geometry and reading this script draws with, as scripts/test_subslip_plots.py checks them
# through this module.
from subslip.texture import (cubic_family, hexagonal_family, quaternion_to_matrix,  # noqa: E402
                             sample_directions, upper_hemisphere_projection)

Result = subslip.Result
__all__ = ["main", "Result", "cubic_family", "hexagonal_family", "quaternion_to_matrix",
           "sample_directions", "upper_hemisphere_projection", "pole_figure_points",
           "hold_intervals", "holds_matter", "peak_at_start"]
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


class Output:
    """Where and how pictures are saved: directory, format (png, pdf, svg), resolution."""

    def __init__(self, directory, fmt="png", dpi=100.0):
        self.directory, self.format, self.dpi = directory, fmt, dpi

    def save(self, fig, stem):
        path = os.path.join(self.directory, f"{stem}.{self.format}")
        fig.savefig(path, dpi=self.dpi)
        plt.close(fig)
        print(path)
        return path


def legend(ax, count):
    if count > 1:
        ax.legend(fontsize="small" if count <= 8 else "x-small", ncol=1 if count <= 10 else 2)


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
    curves = []  # (case, i, j, stress, strain, time)
    for name in usable:
        case = result.case(name)
        stress, strain = case.series("macro/stress"), case.series("macro/strain")  # (n, 3, 3)
        i, j = component or case.loading_component() or largest_component(strain[-1])
        time = case.time() if "macro/time" in case else None
        curves.append((case, i, j, stress, strain, time))
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
                 label=f"{case.label()} ({label_ij})")
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
    ax1.set_xlabel(f"strain $\\varepsilon_{{{ij}}}$ [1]")
    ax1.set_ylabel(f"stress $\\sigma_{{{ij}}}$ [{stress_unit}]")
    ax1.set_title("loading component (largest prescribed $L_{ij}$)")
    ax2.set_xlabel("von Mises strain [1]")
    ax2.set_ylabel(f"von Mises stress [{stress_unit}]")
    ax2.set_title("von Mises")
    if ax_log is not None:
        ax_log.set_xscale("log")
        ax_log.set_xlabel(f"|strain $\\varepsilon_{{{ij}}}$| [1], logarithmic")
        ax_log.set_ylabel(f"stress $\\sigma_{{{ij}}}$ [{stress_unit}]")
        ax_log.set_title("the start (peak)")
    if ax_time is not None:
        ax_time.set_xlabel(f"time [{time_unit}]")
        ax_time.set_ylabel(f"stress $\\sigma_{{{ij}}}$ [{stress_unit}]")
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
    legend(ax, drawn)
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
        label = f"strain $\\varepsilon_{{{ij[0] + 1}{ij[1] + 1}}}$ [1]"
        return case.series("macro/strain")[rows, ij[0], ij[1]], label
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


def draw_pole_figure(ax, quaternions, vectors, marker_size):
    X, Y = pole_figure_points(quaternions, vectors)
    ax.add_patch(plt.Circle((0, 0), 1.0, fill=False, lw=1.0, color="k"))
    ax.plot([-1, 1], [0, 0], color="0.8", lw=0.6)
    ax.plot([0, 0], [-1, 1], color="0.8", lw=0.6)
    ax.scatter(X, Y, s=marker_size, c="C0", alpha=0.6, linewidths=0)
    ax.text(1.06, 0.0, "x", ha="left", va="center")
    ax.text(0.0, 1.06, "y", ha="center", va="bottom")
    ax.set_xlim(-1.15, 1.15)
    ax.set_ylim(-1.15, 1.15)
    ax.set_aspect("equal")
    ax.axis("off")


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
    marker = float(np.clip(6000.0 / (grains * len(families[0][1])), 1.0, 40.0))
    fig, axes = plt.subplots(len(drawn), 3, figsize=(9, 3.1 * len(drawn) + 0.5), squeeze=False)
    for row, (label, q) in enumerate(drawn):
        for col, (family, vectors) in enumerate(families):
            ax = axes[row][col]
            draw_pole_figure(ax, q, vectors, marker)
            ax.set_title(f"{family}, {label}", fontsize="medium")
    grain_text = f"{grains} grain{'s' if grains != 1 else ''}"
    frame = "sample frame, z towards the viewer, upper hemisphere, equal area"
    fig.suptitle(f"{heading(result, f'pole figures, case {name}')}\n{grain_text}; "
                 f"{frame}", fontsize="medium")
    fig.tight_layout()
    return output.save(fig, f"pole_figures_{file_safe(name)}")


def parse_component(text_ij):
    if not re.fullmatch(r"[123][123]", text_ij):
        raise argparse.ArgumentTypeError("give two digits 1-3, e.g. 33 or 12")
    return int(text_ij[0]) - 1, int(text_ij[1]) - 1


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


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("result", help="a subslip result file (HDF5)")
    parser.add_argument("-o", "--output", help="directory for the pictures "
                        "(default: RESULT without .h5, plus _plots)")
    parser.add_argument("--case", help="only this case (default: every case)")
    parser.add_argument("--component", type=parse_component,
                        help="stress-strain component ij (default: the largest prescribed L_ij)")
    parser.add_argument("--format", choices=FORMATS, default="png",
                        help="picture format (default: png; pdf and svg are vector graphics)")
    parser.add_argument("--dpi", type=positive, default=100.0,
                        help="resolution of png pictures in dots per inch (default: 100)")
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
    output = Output(out_dir, args.format, args.dpi)
    written = [plot_stress_strain(result, cases, output, args.component),
               plot_traction_ratio(result, cases, output)]
    if result.scene_kind == "crystal":
        for name in cases:
            written.append(plot_slip_activity(result, name, output))
            written.append(plot_pole_figures(result, name, output))
    count = sum(p is not None for p in written)
    message(f"{count} picture{'s' if count != 1 else ''} in {out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
