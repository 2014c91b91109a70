"""Reading a subslip result file: cases, their valid rows, units, tensors in one convention.

Layout (docs/scenes.md, "Result file layout"): root attributes, /units, /cases/<case>/...,
/progress. A series is laid out whole before the run (rows reserved, NaN or INT_MIN) and filled
as the run goes; /progress/rows[case] counts its valid rows and /progress/state says whether
the case was started. Every series read here is cut to those rows, so NaN padding, rows left
over from before a restart and cases a killed run never reached do not show up. Files without
/progress (format version 1, trimmed at the end) have every row valid.
"""

import functools
import io
import os

import numpy as np

from . import csv_export, derived, tensors, texture
from ._deps import require

h5py = require("h5py")

CASE_STATES = {0: "not_started", 1: "running", 2: "completed", 3: "failed"}
# The output fields themselves are not listed here: the file names them (its datasets, with
# their units and descriptions), and a call that needs one says so (Case._need).


class NotAResult(ValueError):
    """A readable HDF5 file that is not a subslip result."""


class MissingData(LookupError):
    """A quantity that needs data the file does not hold (the message says which)."""


def decoded(value):
    """An attribute value as Python data: str for strings (h5py gives str or bytes, and
    reserved fixed-length strings come NUL-padded), lists of str, numbers, numpy arrays."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace").rstrip("\0")
    if isinstance(value, np.ndarray) and value.dtype.kind in "OSU":
        return [decoded(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return value.item()
    return value


def text_attribute(obj, name, default=None):
    value = decoded(obj.attrs[name]) if name in obj.attrs else default
    return value if isinstance(value, str) or value is default else str(value)


def open(path):  # noqa: A001  (subslip.open mirrors h5py.File / builtins.open on purpose)
    """Opens a result file: `with subslip.open("run.h5") as r: ...`."""
    return Result(path)


class Result:
    """A result file: `cases` (the started ones, in run order), `scene_kind`, `completed`,
    `units`, `title`, `case(name)`. Close it (or use `with`)."""

    def __init__(self, path, image=None):
        """`path`: the file; with `image` (the bytes of a result file, as subslip.run returns
        one), only the name the result goes by, and the file is read from memory."""
        self.path = os.fspath(path)
        self.image = image
        self.file = h5py.File(io.BytesIO(image) if image is not None else self.path, "r")
        try:
            self._read_header()
        except Exception:
            self.file.close()
            raise

    def _read_header(self):
        attrs = self.file.attrs
        if text_attribute(self.file, "format", "") != "subslip":
            raise NotAResult(f"{self.path}: not a subslip result file "
                             "(no root attribute format = \"subslip\")")
        self.scene_kind = text_attribute(self.file, "scene_kind", "")
        self.title = text_attribute(self.file, "title", "")
        self.format_version = int(attrs.get("format_version", 1))
        self.completed = int(attrs.get("completed", 0)) == 1
        # Format 3: the run ended and every series was rewritten with exactly its rows.
        self.finished = int(attrs.get("finished", 0)) == 1
        self.write_error = text_attribute(self.file, "write_error", "")
        units = self.file.get("units")
        self.units = {k: decoded(v) for k, v in units.attrs.items()} if units else {}
        self.all_cases = self._case_names()
        self._rows, self._states, self._grain_rows = self._progress()
        self.cases = [n for n in self.all_cases if self.state(n) != "not_started"]

    def _case_names(self):
        """Run order (/cases attribute `names`), then any group it does not list."""
        cases = self.file.get("cases")
        if cases is None:  # killed before the layout was complete
            return []
        names = [decoded(n) if isinstance(n, bytes) else str(n)
                 for n in cases.attrs.get("names", [])]
        return names + [n for n in cases.keys() if n not in names]

    def _progress(self):
        """Valid rows (None: all) and state of each case, from /progress when it has one entry
        per case (as `subslip post` reads it)."""
        rows = {n: None for n in self.all_cases}
        states = {n: "unknown" for n in self.all_cases}
        grain_rows = dict(rows)
        progress = self.file.get("progress")
        if progress is None or "rows" not in progress or "state" not in progress:
            return rows, states, grain_rows
        counts, codes = progress["rows"][()], progress["state"][()]
        if not len(counts) == len(codes) == len(self.all_cases):
            return rows, states, grain_rows
        # Format 3 counts the per-grain rows apart (output.grains_at may write fewer).
        grain_counts = progress["grain_rows"][()] if "grain_rows" in progress else counts
        if len(grain_counts) != len(counts):
            grain_counts = counts
        for name, count, code, grain_count in zip(self.all_cases, counts, codes, grain_counts):
            rows[name] = int(count) if count >= 0 else None
            grain_rows[name] = int(grain_count) if grain_count >= 0 else None
            states[name] = CASE_STATES.get(int(code), "unknown")
        return rows, states, grain_rows

    def state(self, name):
        """"not_started", "running" (or killed), "completed", "failed"; "unknown" for a file
        without /progress."""
        self._check_name(name)
        if name not in self.file.get("cases", {}):
            return "not_started"
        return self._states[name]

    def valid_rows(self, name):
        """How many rows of the case's series are valid (None: all of them)."""
        self._check_name(name)
        return 0 if self.state(name) == "not_started" else self._rows[name]

    def valid_grain_rows(self, name):
        """How many rows of the case's per-grain series (grains/...) are valid (None: all)."""
        self._check_name(name)
        return 0 if self.state(name) == "not_started" else self._grain_rows[name]

    def case(self, name):
        """The case `name`, by its name as the run showed it ("speed=1 mm/min") or as its
        group is named ("speed=1 mm_min"); a case the run never started has no rows."""
        name = self._group_of(name)
        self._check_name(name)
        group = self.file["cases"].get(name)
        return Case(self, name, group, self.valid_rows(name), self.valid_grain_rows(name))

    def shown_name(self, name):
        """The name the run showed for the case stored as group `name` (its `name`
        attribute: a '/' of a value's unit is stored as '_' in the group's name)."""
        group = self.file.get("cases", {}).get(name)
        return text_attribute(group, "name", name) if group is not None else name

    def _group_of(self, name):
        if name in self.all_cases:
            return name
        return next((c for c in self.all_cases if self.shown_name(c) == name), name)

    def _check_name(self, name):
        if name not in self.all_cases:
            raise KeyError(f"{self.path}: no case '{name}'; the file has: "
                           + (", ".join(self.all_cases) or "none"))

    @property
    def scene(self):
        """The scene YAML as run."""
        return self.file["scene"].asstr()[()] if "scene" in self.file else ""

    def close(self):
        self.file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        state = "completed" if self.completed else "NOT completed"
        return f"<subslip result {self.path}: {self.scene_kind}, {state}, cases {self.cases}>"


class Case:
    """One case of a result: its series cut to the valid rows, tensors as (..., 3, 3)."""

    def __init__(self, result, name, group, valid_rows, valid_grain_rows=None):
        self.result = result
        self.name = name
        self.group = group  # None: a case listed but never created (format version 1)
        self.valid_rows = valid_rows  # None: every row
        # Per-grain series (grains/...) may have fewer rows (output.grains_at): format 3
        # counts them apart.
        self.valid_grain_rows = valid_rows if valid_grain_rows is None else valid_grain_rows

    # ------------------------------------------------------------ datasets and attributes

    def __contains__(self, path):
        return self.group is not None and isinstance(self.group.get(path), h5py.Dataset)

    def dataset(self, path):
        if path not in self:
            raise MissingData(f"case '{self.name}' has no dataset '{path}'; it has: "
                              + ", ".join(self.datasets()))
        return self.group[path]

    def datasets(self, under=""):
        """Paths (relative to the case) of every dataset below `under`, in creation order."""
        if self.group is None:
            return []
        base = self.group[under] if under else self.group
        found = []
        for name, obj in base.items():  # creation order: the groups track it
            path = f"{under}/{name}" if under else name
            found += [path] if isinstance(obj, h5py.Dataset) else self.datasets(path)
        return found

    def is_series(self, path):
        """A time series (chunked, one row per output step) rather than a fixed array."""
        return self.dataset(path).chunks is not None

    def raw(self, path):
        """The dataset as stored, a series cut to its valid rows (no reshaping)."""
        d = self.dataset(path)
        rows = self.valid_grain_rows if path.startswith("grains/") else self.valid_rows
        if not self.is_series(path) or rows is None:
            return d[()]
        return d[: min(rows, d.shape[0])]

    def grain_rows(self):
        """The output row (of macro/time and the other macro series) of every per-grain row:
        grains/row (format 3; fewer rows with output.grains_at), else every row."""
        if "grains/row" in self:
            return np.asarray(self.raw("grains/row"), dtype=int)
        return np.arange(len(self.time()))

    def series(self, path):
        """The dataset cut to its valid rows; a 3x3 tensor dataset as (n, 3, 3) (macro) or
        (n, G, 3, 3) (per grain), whatever its stored layout (tensors.LayoutError when the
        layout is one this package does not know)."""
        values = self.raw(path)
        layout = self.tensor_layout(path)
        if layout is None:
            return values
        return tensors.to_matrices(values, layout, f"case '{self.name}': {path}")

    def tensor_layout(self, path):
        """The `components` (format 3) or `layout` / `components` (format 2) text of a tensor
        dataset; None for other data."""
        d = self.dataset(path)
        for name in ("components", "layout"):
            text = text_attribute(d, name)
            if text is not None and tensors.looks_like_tensor(text):
                return text
        return None

    def grains(self, field, grain=None):
        """A per-grain field ("stress", "slip_rate", "weight", ...): (n, G, ...) for series,
        or of one grain (n, ...) with `grain`."""
        values = self.series(f"grains/{field}")
        if grain is None:
            return values
        return values[:, grain] if self.is_series(f"grains/{field}") else values[grain]

    def unit(self, path):
        return text_attribute(self.dataset(path), "unit")

    def description(self, path):
        return text_attribute(self.dataset(path), "description")

    @functools.cached_property
    def attrs(self):
        """The case group's attributes (parameters, summary), decoded (read once: the file is
        open read-only)."""
        if self.group is None:
            return {}
        return {k: decoded(v) for k, v in self.group.attrs.items()}

    def attribute_unit(self, name):
        """The unit of a parameter or summary attribute (its `name.unit` sibling)."""
        return self.attrs.get(f"{name}.unit")

    @property
    def state(self):
        return self.result.state(self.name)

    @property
    def failed(self):
        """Why the case stopped on a numerical failure ("" if it did not)."""
        return self.attrs.get("failed", "") or ""

    # ------------------------------------------------------------ sweeps

    def sweep(self):
        """The swept values of this case: [(path, value, unit or None)], in sweep order."""
        out = []
        for key, value in self.attrs.items():
            if key.startswith("sweep:") and not key.endswith(".unit"):
                path = key[len("sweep:"):]
                out.append((path, value, derived.sweep_unit(self, path)))
        return out

    def label(self):
        """A legend label: the swept values with their units ("speed=200 mm/min"), else the
        case name. A value swept with its own unit ("1 mm/s", converted by subslip into the
        scene's units) is shown as written."""
        parts = []
        for path, value, unit in self.sweep():
            number = f"{value:g}" if isinstance(value, (int, float)) else str(value)
            if derived.written_with_unit(number):
                unit = None
            parts.append(f"{derived.sweep_label(path)}={number}" + (f" {unit}" if unit
                                                                        and unit != "1" else ""))
        return ", ".join(parts) or self.name

    # ------------------------------------------------------------ derived quantities

    def time(self):
        return self.series("macro/time" if "macro/time" in self else "time")

    def von_mises_stress(self, per_grain=False, grain=None):
        """Von Mises stress (n,) of the aggregate at every valid row; with `per_grain`, of
        every grain's grains/stress (n_g, G), or of grain `grain` (n_g,), at the per-grain
        rows (grain_rows())."""
        if per_grain or grain is not None:
            stress = self.series(self._need("grains/stress"))
            return self._of_grain(tensors.von_mises_stress(stress), grain)
        return tensors.von_mises_stress(self.series(self._need("macro/stress")))

    def von_mises_strain(self):
        """Von Mises (equivalent) strain of the aggregate at every valid row (n,); every grain
        of a Taylor aggregate has the aggregate's strain."""
        return tensors.von_mises_strain(self.series(self._need("macro/strain")))

    def grain_weights(self):
        """Volume fractions (G,) summing to 1 (grains/weight, written with every grain field)."""
        w = self.raw(self._need("grains/weight", field=False))
        return w / np.sum(w)

    def slip_system_labels(self):
        d = self.dataset(self._need("grains/slip_systems", field=False))
        return [str(s) for s in decoded(d.attrs.get("labels", []))]

    def schmid_tensors(self):
        """sym(s (x) m) of every slip system, lattice frame (N, 3, 3)."""
        return derived.schmid_tensors(self.raw(self._need("grains/slip_systems", field=False)))

    def slip_activity(self, per_grain=False, grain=None):
        """|slip rate| per slip system at the per-grain rows, unit of grains/slip_rate: the
        grain-weighted mean (n_g, N); with `per_grain`, of every grain (n_g, G, N), or of grain
        `grain` (n_g, N)."""
        rates = self.series(self._need("grains/slip_rate"))
        if per_grain or grain is not None:
            return self._of_grain(np.abs(rates), grain)
        return derived.weighted_mean_abs(rates, self.grain_weights())

    def equivalent_plastic_strain(self, per_grain=False, grain=None):
        """Accumulated von Mises equivalent plastic strain at the per-grain rows: the
        grain-weighted mean (n_g,), with `per_grain` every grain's (n_g, G), or grain
        `grain`'s (n_g,). The sum over output rows of sqrt(2/3 dE:dE), dE = sum_a dgamma_a
        sym(s_a (x) m_a), dgamma the change of grains/slip between rows (exact while no
        system reverses within an output step). Needs grains/slip and grains/slip_systems."""
        slip = self.series(self._need("grains/slip"))
        systems = self.raw(self._need("grains/slip_systems", field=False))
        eps = derived.equivalent_plastic_strain(slip, systems)
        if per_grain or grain is not None:
            return self._of_grain(eps, grain)
        return derived.weighted_mean_abs(eps, self.grain_weights())

    def _of_grain(self, per_grain_values, grain):
        """(n_g, G, ...) values as they are, or of one grain (n_g, ...), checked."""
        if grain is None:
            return per_grain_values
        count = per_grain_values.shape[1]
        if not -count <= grain < count:
            raise IndexError(f"case '{self.name}': grain {grain} is out of range "
                             f"(0 to {count - 1})")
        return per_grain_values[:, grain]

    def grain_time(self):
        """The time of every per-grain row (n_g,): macro/time at grain_rows()."""
        return self.time()[self.grain_rows()]

    def loading_component(self):
        """(i, j) of the largest prescribed L_ij (None without macro/L)."""
        if "macro/L" not in self:
            return None
        segment = self.raw("macro/segment") if "macro/segment" in self else None
        return derived.loading_component(self.series("macro/L"), segment)

    # ------------------------------------------------------------ texture

    def lattice(self):
        """"cubic", "hcp" or "unknown" (custom slip systems), from slip_families."""
        families = self.attrs.get("slip_families", [])
        families = [families] if isinstance(families, str) else list(families)
        if families and all(f.startswith("hcp") for f in families):
            return "hcp"
        if families and all(f.startswith(("fcc", "bcc")) for f in families):
            return "cubic"
        return "unknown"

    def orientations(self, step=-1):
        """Quaternions (G, 4) of every grain at valid row `step` (0: initial, -1: last)."""
        if "grains/orientation" in self:
            q = self.series("grains/orientation")
            if len(q) == 0:
                raise MissingData(f"case '{self.name}' has no valid rows")
            return q[step]
        fixed = step == 0 or self.attrs.get("kinematics") == "small_strain"
        if fixed and "grains/initial_orientation" in self:
            return self.raw("grains/initial_orientation")
        raise MissingData(self._missing("grains/orientation"))

    def pole_figure(self, crystal_vectors, step=-1, projection="equal_area"):
        """(X, Y) of the poles `crystal_vectors` (e.g. texture.cubic_family((1, 0, 0))) of
        every grain at `step`, sample frame (x right, y up), upper hemisphere."""
        return texture.pole_figure_points(self.orientations(step), crystal_vectors, projection)

    def inverse_pole_figure(self, sample_direction=(0.0, 0.0, 1.0), step=-1,
                            projection="equal_area"):
        """(X, Y) of a sample direction in every grain's crystal frame, in the standard
        triangle of the lattice."""
        lattice = self.lattice()
        return texture.inverse_pole_figure_points(self.orientations(step), sample_direction,
                                                  lattice, projection)

    # ------------------------------------------------------------ export

    def to_csv(self, directory, names=None, grain=None, overwrite=False):
        """Writes `names` (dataset or group paths relative to the case; default: every
        dataset) as CSV files `<case>_<path>.csv` in `directory`, as `subslip post --csv`
        does. Returns the paths written."""
        return csv_export.export_case(self, directory, names, grain, overwrite)

    def to_table(self, directory, quantities, grain=None, overwrite=False):
        """Writes one CSV `<case>.csv` in `directory` with a column (or one per component) for
        each of `quantities`: time series of the case ("macro/strain") and derived quantities
        ("macro/von_mises_stress", "grains/equivalent_plastic_strain", ...), as `subslip post
        --csv DIR --quantity ...` does. Returns its path."""
        written = csv_export.export_case(self, directory, grain=grain, overwrite=overwrite,
                                         quantities=quantities)
        return written[0] if written else None

    # ------------------------------------------------------------ helpers

    def _need(self, path, field=True):
        """`path`, or MissingData naming the scene's output setting that writes it; `field`:
        the path is an output field of its own (else it comes with any grain field)."""
        if path not in self:
            raise MissingData(self._missing(path, field))
        return path

    def _missing(self, path, field=True):
        group, _, name = path.rpartition("/")
        if field and group in ("macro", "grains"):
            hint = f"; ask the scene for it: output: {{{group}: [{name}]}}"
        elif group == "grains":  # weight, slip_systems: written with any grain field
            hint = "; ask the scene for grain fields: output: {grains: [...]}"
        else:
            hint = ""
        return f"case '{self.name}' has no {path}{hint}"

    def __repr__(self):
        rows = "all" if self.valid_rows is None else self.valid_rows
        return f"<subslip case '{self.name}': {self.state}, {rows} valid rows>"
