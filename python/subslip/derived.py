"""Quantities derived from a case's arrays: slip activity, equivalent plastic strain, the
loading component, units of swept values.

The measures (von Mises, equivalent plastic strain, grain-weighted means) are computed by the
compiled core (subslip._core over crystal/measures.hpp), the one implementation the run summary
and `subslip post --quantity` use too, so that the package and the program cannot disagree.
"""

import re

import numpy as np

from . import _native


def schmid_tensors(slip_systems):
    """sym(s (x) m) (N, 3, 3) of grains/slip_systems rows (s in columns 0-2, m in 3-5)."""
    systems = np.asarray(slip_systems, dtype=float)
    p = np.einsum("ai,aj->aij", systems[:, :3], systems[:, 3:6])
    return 0.5 * (p + np.swapaxes(p, -1, -2))


def weighted_mean_abs(values, weights):
    """sum_g w_g |values[:, g, ...]| / sum_g w_g: (n, G, ...) -> (n, ...); by the core."""
    return _native.core().weighted_mean_abs(np.asarray(values, dtype=float),
                                            np.asarray(weights, dtype=float))


def equivalent_plastic_strain(slip, slip_systems):
    """Accumulated equivalent plastic strain (n, G) from accumulated signed slip (n, G, N) and
    the grains/slip_systems rows (N, 6): the sum over rows of sqrt(2/3 dE:dE), dE = sum_a
    dgamma_a sym(s_a (x) m_a); row 0 (the initial state) is 0. By the core
    (crystal/measures.hpp), as `subslip post --quantity grains/equivalent_plastic_strain`."""
    return _native.core().equivalent_plastic_strain(np.asarray(slip, dtype=float),
                                                    np.asarray(slip_systems, dtype=float))


def loading_component(L, segment=None):
    """(i, j) of the largest prescribed velocity-gradient component, as `subslip run` reports
    it, from the L series (n, 3, 3). A prescribed L_ij is constant within a segment, while a
    free (solved) one changes from step to step; the file does not flag which is which, so
    this tells them apart by that. None without increments."""
    L = np.asarray(L, dtype=float).reshape(-1, 9)[1:]  # row 0: the initial state
    if len(L) == 0:
        return None
    if segment is not None:
        allowed = max(len(np.unique(np.asarray(segment)[1:len(L) + 1])) - 1, 0)
    else:
        allowed = len(L) // 10
    best, largest = None, 0.0
    for c in range(9):
        changes = np.count_nonzero(np.diff(L[:, c]))
        size = np.max(np.abs(L[:, c]))
        if changes <= allowed and size > largest:
            best, largest = divmod(c, 3), size
    return best


def sweep_label(path):
    """The part of a sweep path a case name shows: from the last key on ("L[2][2]" of
    "loading[0].L[2][2]", "speed" of "loading[0].slide.speed")."""
    return path.rsplit(".", 1)[-1]


def sweep_key(path):
    """The last key of a sweep path, without indices ("L" of "loading[0].L[2][2]")."""
    return re.sub(r"\[[^\]]*\]", "", sweep_label(path))


# Units of scene keys that have no attribute of their name in the case group, in terms of the
# file's /units (docs/scenes.md, `loading` tables).
LOADING_UNITS = {
    "L": "1/{time}", "stress": "{stress}", "traction": "{stress}", "strain": "1",
    "speed": "{length}/{time}", "velocity": "{length}/{time}", "distance": "{length}",
    "duration": "{time}", "spread_deg": "deg", "euler_deg": "deg",
}


_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def written_with_unit(text):
    """Whether a swept value's text carries a unit of its own ("1 mm/s", "[0.2 mm/s, 0 mm/s]",
    "60min"), as scenes may write values (docs/scenes.md, "Units"); "1.5e-3", "[1, 0]" do not."""
    rest = _NUMBER.sub("", text)
    return any(c.isalpha() or c in "/%" for c in rest)


def sweep_unit(case, path):
    """The unit of a swept value, or None when unknown (names). Format 3 stores it as the
    attribute `sweep:<path>.unit`; for older files it is taken from the case attribute of the
    same key (`eta_v.unit`), else from the scene's loading keys."""
    attrs = case.attrs
    if f"sweep:{path}.unit" in attrs:
        return attrs[f"sweep:{path}.unit"]
    key = sweep_key(path)
    if f"{key}.unit" in attrs:
        return attrs[f"{key}.unit"]
    template = LOADING_UNITS.get(key)
    if template is None:
        return None
    units = case.result.units
    try:
        return template.format(**units)
    except KeyError:  # e.g. a crystal file has no length unit
        return None
