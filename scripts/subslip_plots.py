#!/usr/bin/python3
"""The standard pictures of a subslip result file (docs/scenes.md), as PNG files.

    scripts/subslip_plots.py RESULT.h5 [-o DIR] [--case NAME] [--component IJ]

Draws what the file has data for and says what it skips:
  stress_strain.png          crystal: the loading component sigma_ij against eps_ij and the von
                             Mises stress against the von Mises strain, one curve per case
  traction_ratio.png         contact: f_t/f_n against the sliding distance (linear and
                             logarithmic), one curve per case
  slip_activity_<case>.png   crystal with grain fields slip_rate and/or slip: the grain average
                             (weighted) of |slip rate| and of |accumulated slip| per slip system
                             against the loading strain
  pole_figures_<case>.png    crystal with grain orientations: {111} {100} {110} pole figures
                             ({0001} {10-10} {11-20} for hcp) of the initial and final texture

Pole figures: sample frame (x right, y up, z towards the viewer), upper hemisphere, equal-area
(Lambert) projection scaled to the unit circle. The file stores each orientation as the
quaternion of g with v_crystal = g v_sample (passive, Rowenhorst et al. 2015, P = -1), so a
crystal direction c points along g^T c in the sample.

Needs Debian's python3-h5py, python3-numpy and python3-matplotlib; run with /usr/bin/python3.
"""

import argparse
import itertools
import os
import re
import sys

import h5py
import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)

DPI = 100


def message(text):
    print("subslip_plots: " + text, file=sys.stderr)


def text(value):
    """An HDF5 string attribute as str (h5py gives str or bytes depending on storage)."""
    return value.decode() if isinstance(value, bytes) else str(value)


def file_safe(name):
    """The file-name form `subslip post` uses: letters, digits and ._=+- kept, others '_'."""
    return re.sub(r"[^A-Za-z0-9._=+-]", "_", name)


# ---------------------------------------------------------------- rotations and projections


def quaternion_to_matrix(q):
    """Orientation matrices g (..., 3, 3) of unit quaternions q (..., 4) = (w, x, y, z).

    Passive convention of Rowenhorst et al. (2015) with P = -1, as subslip writes them
    (include/subslip/crystal/rotation.hpp): v_crystal = g v_sample. A rotation by omega about n
    is q = (cos(omega/2), n sin(omega/2)); e.g. 90 deg about z gives g = [[0,1,0],[-1,0,0],[0,0,1]].
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    g = np.empty(q.shape[:-1] + (3, 3))
    g[..., 0, 0] = w * w + x * x - y * y - z * z
    g[..., 0, 1] = 2.0 * (x * y + w * z)
    g[..., 0, 2] = 2.0 * (x * z - w * y)
    g[..., 1, 0] = 2.0 * (x * y - w * z)
    g[..., 1, 1] = w * w - x * x + y * y - z * z
    g[..., 1, 2] = 2.0 * (y * z + w * x)
    g[..., 2, 0] = 2.0 * (x * z + w * y)
    g[..., 2, 1] = 2.0 * (y * z - w * x)
    g[..., 2, 2] = w * w - x * x - y * y + z * z
    return g


def cubic_family(hkl):
    """All unit vectors of the cubic form {hkl}, both signs (permutations and sign changes)."""
    vectors = set()
    for perm in itertools.permutations(hkl):
        for signs in itertools.product((1, -1), repeat=3):
            vectors.add(tuple(s * p for s, p in zip(signs, perm)))
    v = np.array(sorted(vectors), dtype=float)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def hexagonal_family(name):
    """Unit plane normals of {0001}, {10-10} or {11-20}, both signs, in subslip's hexagonal
    lattice frame (a1 along x, c along z; include/subslip/crystal/slip_systems.hpp)."""
    if name == "0001":
        return np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    start = {"10-10": 30.0, "11-20": 0.0}[name]
    angles = np.radians(start + 60.0 * np.arange(6))
    return np.stack([np.cos(angles), np.sin(angles), np.zeros(6)], axis=1)


def pole_families(lattice):
    if lattice == "hcp":
        return [("{0001}", hexagonal_family("0001")), ("{10-10}", hexagonal_family("10-10")),
                ("{11-20}", hexagonal_family("11-20"))]
    return [("{111}", cubic_family((1, 1, 1))), ("{100}", cubic_family((1, 0, 0))),
            ("{110}", cubic_family((1, 1, 0)))]


def sample_directions(g, crystal_vectors):
    """Sample-frame components g^T c of crystal directions c: (grains, vectors, 3)."""
    g = np.asarray(g).reshape(-1, 3, 3)
    return np.einsum("gji,vj->gvi", g, crystal_vectors)


def upper_hemisphere_projection(v):
    """Equal-area projection of the upper-hemisphere unit vectors among v (..., 3) onto the
    unit disk: (x, y) / sqrt(1 + z), which maps z = 1 to the centre and z = 0 to the rim.
    A pole on the equator is kept with both signs (the two rim points)."""
    v = np.asarray(v, dtype=float).reshape(-1, 3)
    v = v[v[:, 2] > -1e-9]
    z = np.clip(v[:, 2], 0.0, 1.0)
    scale = 1.0 / np.sqrt(1.0 + z)
    return v[:, 0] * scale, v[:, 1] * scale


def pole_figure_points(quaternions, crystal_vectors):
    """Projected (X, Y) of the poles of every orientation."""
    return upper_hemisphere_projection(
        sample_directions(quaternion_to_matrix(quaternions), crystal_vectors))


# ---------------------------------------------------------------- reading


class NotAResult(Exception):
    pass


class Case:
    """One case group. A run that did not finish reserves rows ahead in its time series (NaN,
    or left over from before a restart); /progress/rows says how many are valid, and
    series() returns only those. Fixed arrays (weight, initial_orientation) are read as they
    are, with case[path]."""

    def __init__(self, group, valid_rows):
        self.group = group
        self.valid_rows = valid_rows  # None: every row

    def __contains__(self, path):
        return path in self.group

    def __getitem__(self, path):
        return self.group[path]

    @property
    def attrs(self):
        return self.group.attrs

    def series(self, path):
        d = self.group[path]
        if self.valid_rows is None or d.chunks is None:
            return d[()]
        return d[: self.valid_rows]


class Result:
    def __init__(self, path):
        self.path = path
        self.file = h5py.File(path, "r")
        attrs = self.file.attrs
        if text(attrs.get("format", "")) != "subslip":
            raise NotAResult(f"{path}: not a subslip result file (no root attribute format)")
        self.kind = text(attrs.get("scene_kind", ""))
        self.title = text(attrs.get("title", ""))
        self.completed = int(attrs.get("completed", 0)) == 1
        units = self.file.get("units")
        self.units = {k: text(v) for k, v in units.attrs.items()} if units is not None else {}
        cases = self.file.get("cases")
        if cases is None:  # killed before the first case
            self.case_names = []
            return
        names = [text(n) for n in cases.attrs.get("names", list(cases.keys()))]
        # /progress (docs/scenes.md): valid rows and state (0 = not started) per case.
        rows, states = [None] * len(names), [None] * len(names)
        progress = self.file.get("progress")
        if progress is not None and "rows" in progress and "state" in progress:
            if len(progress["rows"]) == len(names) == len(progress["state"]):
                rows = [int(r) for r in progress["rows"][()]]
                states = [int(s) for s in progress["state"][()]]
        self.valid_rows = dict(zip(names, rows))
        self.case_names = [n for n, state in zip(names, states) if n in cases and state != 0]

    def case(self, name):
        return Case(self.file["cases"][name], self.valid_rows.get(name))

    def heading(self, what=""):
        """`what: title`, marked when the run did not complete."""
        note = "" if self.completed else " (INCOMPLETE run)"
        parts = [p for p in (what, self.title) if p]
        return ": ".join(parts) + note


def loading_component(case):
    """(i, j) of the largest prescribed velocity-gradient component, as `subslip run` reports
    it. A prescribed L_ij is constant within a segment, while a free (solved) one changes from
    step to step; the file does not flag which is which, so this tells them apart by that."""
    if "macro/L" not in case:
        return None
    L = case.series("macro/L")[1:]
    if len(L) == 0:
        return None
    if "macro/segment" in case:
        allowed = max(len(np.unique(case.series("macro/segment")[1:])) - 1, 0)
    else:
        allowed = max(len(L) // 10, 0)
    best, largest = None, 0.0
    for c in range(9):
        changes = np.count_nonzero(np.diff(L[:, c]))
        size = np.max(np.abs(L[:, c]))
        if changes <= allowed and size > largest:
            best, largest = divmod(c, 3), size
    return best


def largest_component(tensor):
    """(i, j) of the largest absolute component of a row-major 3x3 tensor."""
    return divmod(int(np.argmax(np.abs(tensor))), 3)


def von_mises(tensors, kind):
    t = np.asarray(tensors).reshape(-1, 3, 3)
    sym = 0.5 * (t + np.transpose(t, (0, 2, 1)))
    dev = sym - np.trace(sym, axis1=1, axis2=2)[:, None, None] / 3.0 * np.eye(3)
    factor = 1.5 if kind == "stress" else 2.0 / 3.0
    return np.sqrt(factor * np.sum(dev * dev, axis=(1, 2)))


# ---------------------------------------------------------------- pictures


def save(fig, out_dir, name):
    path = os.path.join(out_dir, name)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    print(path)
    return path


def legend(ax, count):
    if count > 1:
        ax.legend(fontsize="small" if count <= 8 else "x-small", ncol=1 if count <= 10 else 2)


def plot_stress_strain(result, cases, out_dir, component=None):
    if result.kind != "crystal":
        message("stress-strain: not a crystal result, skipped")
        return None
    usable = [c for c in cases
              if "macro/stress" in result.case(c) and "macro/strain" in result.case(c)]
    if not usable:
        message("stress-strain: no macro/stress and macro/strain in the file, skipped")
        return None
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.2))
    stress_unit = result.units.get("stress", "")
    components = set()
    for name in usable:
        case = result.case(name)
        stress = case.series("macro/stress")
        strain = case.series("macro/strain")
        ij = component or loading_component(case) or largest_component(strain[-1])
        k = 3 * ij[0] + ij[1]
        label_ij = f"{ij[0] + 1}{ij[1] + 1}"
        components.add(label_ij)
        ax1.plot(strain[:, k], stress[:, k], label=f"{name} ({label_ij})")
        ax2.plot(von_mises(strain, "strain"), von_mises(stress, "stress"), label=name)
    ij = components.pop() if len(components) == 1 else "ij"
    ax1.set_xlabel(f"strain $\\varepsilon_{{{ij}}}$ [1]")
    ax1.set_ylabel(f"stress $\\sigma_{{{ij}}}$ [{stress_unit}]")
    ax1.set_title("loading component (largest prescribed $L_{ij}$)")
    ax2.set_xlabel("von Mises strain [1]")
    ax2.set_ylabel(f"von Mises stress [{stress_unit}]")
    ax2.set_title("von Mises")
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
        legend(ax, len(usable))
    fig.suptitle(result.heading("stress-strain"), fontsize="medium")
    fig.tight_layout()
    return save(fig, out_dir, "stress_strain.png")


def plot_traction_ratio(result, cases, out_dir):
    if result.kind != "contact":
        message("traction ratio: not a contact result, skipped")
        return None
    # Linear (the paper's view) and logarithmic in the distance (resolves the peak).
    fig, (ax, ax_log) = plt.subplots(1, 2, figsize=(11, 4.3))
    drawn = 0
    length = result.units.get("length", "")
    for name in cases:
        case = result.case(name)
        if "ratio" not in case:
            continue
        if "slip_path" in case:
            x, xlabel = case.series("slip_path"), f"sliding distance [{length}]"
        elif "slip" in case:
            x, xlabel = case.series("slip")[:, 0], f"sliding displacement u_x [{length}]"
        else:
            continue
        ratio = case.series("ratio")
        ax.plot(x, ratio, label=name)
        positive = x > 0
        ax_log.plot(x[positive], ratio[positive], label=name)
        drawn += 1
    if drawn == 0:
        plt.close(fig)
        message("traction ratio: no ratio with slip_path or slip in the file, skipped")
        return None
    ax_log.set_xscale("log")
    for a in (ax, ax_log):
        a.set_xlabel(xlabel)
        a.set_ylabel("traction ratio $f_t/f_n$ [1]")
        a.grid(alpha=0.3)
    legend(ax, drawn)
    fig.suptitle(result.heading("traction ratio"), fontsize="medium")
    fig.tight_layout()
    return save(fig, out_dir, "traction_ratio.png")


def grain_weights(case, grains):
    if "grains/weight" in case:
        w = case["grains/weight"][()]
        return w / np.sum(w)
    return np.full(grains, 1.0 / grains)


def system_families(case, count):
    """Per slip system: its family and its label without the family, from the `labels` of
    grains/slip_systems ("fcc_111_110 (1 1 1)[1 0 -1]")."""
    labels = []
    if "grains/slip_systems" in case and "labels" in case["grains/slip_systems"].attrs:
        labels = [text(s) for s in case["grains/slip_systems"].attrs["labels"]]
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
    ij = loading_component(case)
    if "macro/strain" in case and ij is not None:
        label = f"strain $\\varepsilon_{{{ij[0] + 1}{ij[1] + 1}}}$ [1]"
        return case.series("macro/strain")[:, 3 * ij[0] + ij[1]], label
    return case.series("macro/time"), f"time [{result.units.get('time', '')}]"


def plot_slip_activity(result, name, out_dir):
    case = result.case(name)
    fields = [f for f in ("slip_rate", "slip") if f"grains/{f}" in case]
    if result.kind != "crystal" or not fields or "macro/time" not in case:
        message(f"slip activity ({name}): no grains/slip_rate or grains/slip in the file, skipped")
        return None
    x, xlabel = loading_strain(result, case)
    count = case[f"grains/{fields[0]}"].shape[2]
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
    time_unit = result.units.get("time", "")
    for ax, field in zip(axes[0], fields):
        data = case.series(f"grains/{field}")  # [n, G, N]
        mean = np.einsum("ngs,g->ns", np.abs(data), grain_weights(case, data.shape[1]))
        for a in range(count):
            ax.plot(x, mean[:, a], color=colours[a], label=legend_labels[a], lw=1.2)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"mean |slip rate| [1/{time_unit}]" if field == "slip_rate"
                      else "mean |accumulated slip| [1]")
        ax.grid(alpha=0.3)
    handles, names = axes[0][0].get_legend_handles_labels()
    right = 1.0 - legend_width / width
    fig.legend(handles, names, loc="center left", bbox_to_anchor=(right, 0.5),
               fontsize="x-small", title=distinct[0] if per_system and len(distinct) == 1 else None,
               title_fontsize="x-small", frameon=False)
    fig.suptitle(f"slip activity per slip system (weighted grain average), case {name}\n"
                 + result.heading(), fontsize="medium")
    fig.tight_layout(rect=(0, 0, right, 1))
    return save(fig, out_dir, f"slip_activity_{file_safe(name)}.png")


def lattice_of(case):
    families = [text(f) for f in np.atleast_1d(case.attrs.get("slip_families", []))]
    if families and all(f.startswith("hcp") for f in families):
        return "hcp"
    if families and all(f.startswith(("fcc", "bcc")) for f in families):
        return "cubic"
    return "unknown"


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


def plot_pole_figures(result, name, out_dir):
    case = result.case(name)
    textures = []
    orientations = case.series("grains/orientation") if "grains/orientation" in case else []
    if "grains/initial_orientation" in case:
        textures.append(("initial", case["grains/initial_orientation"][()]))
    elif len(orientations) > 0:
        textures.append(("initial", orientations[0]))
    if len(orientations) > 1:
        final_time = case.series("macro/time")[-1] if "macro/time" in case else None
        label = "final" + (f" (t = {final_time:.4g} {result.units.get('time', '')})"
                           if final_time is not None else "")
        textures.append((label, orientations[-1]))
    if result.kind != "crystal" or not textures:
        message(f"pole figures ({name}): no grain orientations in the file, skipped")
        return None
    lattice = lattice_of(case)
    if lattice == "unknown":
        message(f"pole figures ({name}): custom slip systems, lattice unknown; drawing cubic poles")
    families = pole_families(lattice)
    grains = textures[0][1].shape[0]
    marker = float(np.clip(6000.0 / (grains * len(families[0][1])), 1.0, 40.0))
    fig, axes = plt.subplots(len(textures), 3, figsize=(9, 3.1 * len(textures) + 0.5),
                             squeeze=False)
    for row, (label, q) in enumerate(textures):
        for col, (family, vectors) in enumerate(families):
            ax = axes[row][col]
            draw_pole_figure(ax, q, vectors, marker)
            ax.set_title(f"{family}, {label}", fontsize="medium")
    grain_text = f"{grains} grain{'s' if grains != 1 else ''}"
    frame = "sample frame, z towards the viewer, upper hemisphere, equal area"
    fig.suptitle(f"{result.heading(f'pole figures, case {name}')}\n{grain_text}; {frame}",
                 fontsize="medium")
    fig.tight_layout()
    return save(fig, out_dir, f"pole_figures_{file_safe(name)}.png")


def parse_component(text_ij):
    if not re.fullmatch(r"[123][123]", text_ij):
        raise argparse.ArgumentTypeError("give two digits 1-3, e.g. 33 or 12")
    return int(text_ij[0]) - 1, int(text_ij[1]) - 1


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("result", help="a subslip result file (HDF5)")
    parser.add_argument("-o", "--output", help="directory for the PNG files "
                        "(default: RESULT without .h5, plus _plots)")
    parser.add_argument("--case", help="only this case (default: every case)")
    parser.add_argument("--component", type=parse_component,
                        help="stress-strain component ij (default: the largest prescribed L_ij)")
    args = parser.parse_args(argv)
    if not os.path.isfile(args.result):
        parser.exit(2, f"subslip_plots: error: {args.result}: no such file\n")
    try:
        result = Result(args.result)
    except OSError as e:
        parser.exit(2, f"subslip_plots: error: {args.result}: not readable as HDF5 ({e})\n")
    except NotAResult as e:
        parser.exit(2, f"subslip_plots: error: {e}\n")
    cases = result.case_names
    if args.case is not None:
        if args.case not in cases:
            parser.exit(2, f"subslip_plots: error: {args.result}: no case '{args.case}'; "
                        f"the file has: {', '.join(cases)}\n")
        cases = [args.case]
    out_dir = args.output or os.path.splitext(args.result)[0] + "_plots"
    os.makedirs(out_dir, exist_ok=True)
    written = [plot_stress_strain(result, cases, out_dir, args.component),
               plot_traction_ratio(result, cases, out_dir)]
    if result.kind == "crystal":
        for name in cases:
            written.append(plot_slip_activity(result, name, out_dir))
            written.append(plot_pole_figures(result, name, out_dir))
    count = sum(p is not None for p in written)
    message(f"{count} picture{'s' if count != 1 else ''} in {out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
