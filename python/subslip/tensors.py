"""Second-order tensors of a result file as (..., 3, 3) arrays, and their von Mises measures
(computed by the compiled core, subslip._core, the one implementation `subslip post` uses too).

Format 3 stores every tensor as it is used: [n, 3, 3] (macro) and [n, G, 3, 3] (per grain),
[..., i, j] the component ij, symmetric ones in full, with the attribute `components` =
TENSOR_CONVENTION. Format 2 stored macro tensors as 9 columns with the attribute `layout =
"row-major 3x3: 11 12 13 21 22 23 31 32 33"` and per-grain symmetric tensors as 6 columns
with `components = "11 22 33 23 13 12"` (tensor components, no Voigt factor 2 on the shears,
no Mandel sqrt 2). Every layout is read from its attribute rather than assumed, so that a
layout this module does not know stops with a message instead of silently wrong components.
"""

import re

import numpy as np

from . import _native

# The `components` attribute of a format-3 tensor dataset (h5::kTensorConvention).
TENSOR_CONVENTION = ("3x3 tensor: [..., i, j] is the component ij (i the row, j the column); "
                     "symmetric tensors are stored in full")

# Prefixes (the text before ':') that say the columns are plain tensor components. Any other
# prefix (e.g. "Mandel") may mean scaled components: refused, not guessed.
PLAIN_PREFIXES = ("", "row-major 3x3")
COMPONENT = re.compile(r"[123][123]")


class LayoutError(ValueError):
    """A tensor dataset whose layout attribute this module cannot interpret."""


def parse_layout(text):
    """(prefix, tokens) of a layout text: "row-major 3x3: 11 12 ..." -> ("row-major 3x3",
    ["11", "12", ...]); a text without ':' has an empty prefix."""
    prefix, _, rest = text.rpartition(":")
    return prefix.strip(), rest.split()


def is_full_tensor(text, shape):
    """True for a format-3 tensor: its trailing axes are (3, 3) and the attribute says so."""
    return text == TENSOR_CONVENTION and tuple(shape[-2:]) == (3, 3)


def is_tensor_layout(text):
    """True when the layout's words all name tensor components ("11", "23", ...)."""
    _, tokens = parse_layout(text)
    return bool(tokens) and all(COMPONENT.fullmatch(t) for t in tokens)


def looks_like_tensor(text):
    """True for a layout text that describes a 3x3 tensor, known or not: its words are
    component names, or it says so ("3x3", "tensor", "Mandel", "Voigt"). "w x y z" and
    "one value per slip system" are not tensors."""
    words = ("3x3", "tensor", "mandel", "voigt")
    return is_tensor_layout(text) or any(w in text.lower() for w in words)


def component_pairs(text, columns, where="dataset"):
    """For each column, the (i, j) index pairs (0-based) it fills: one pair for a diagonal or
    a full-tensor component, both (i, j) and (j, i) for an off-diagonal one of a symmetric
    layout. Raises LayoutError unless the columns give a complete 3x3 tensor."""
    prefix, tokens = parse_layout(text)
    if prefix.lower() not in PLAIN_PREFIXES:
        raise LayoutError(f"{where}: unknown tensor layout '{text}' (known: plain tensor "
                          f"components, prefixes {PLAIN_PREFIXES[1:]} or none)")
    if len(tokens) != columns or not all(COMPONENT.fullmatch(t) for t in tokens):
        raise LayoutError(f"{where}: layout '{text}' does not name {columns} tensor components")
    ij = [(int(t[0]) - 1, int(t[1]) - 1) for t in tokens]
    if len(set(ij)) != len(ij):
        raise LayoutError(f"{where}: layout '{text}' names a component twice")
    if columns == 9:
        return [[p] for p in ij]
    symmetric = {tuple(sorted(p)) for p in ij}
    if columns == 6 and len(symmetric) == 6:
        return [[p] if p[0] == p[1] else [p, p[::-1]] for p in ij]
    raise LayoutError(f"{where}: layout '{text}' is neither a full (9) nor a symmetric (6) "
                      "3x3 tensor")


def to_matrices(values, layout, where="dataset"):
    """(..., k) columns in `layout` -> (..., 3, 3) tensors (k = 9 or 6); a format-3 tensor,
    already (..., 3, 3), as it is."""
    values = np.asarray(values, dtype=float)
    if is_full_tensor(layout, values.shape):
        return values
    if layout == TENSOR_CONVENTION:
        raise LayoutError(f"{where}: a 3x3 tensor whose trailing axes are {values.shape[-2:]}")
    pairs = component_pairs(layout, values.shape[-1], where)
    out = np.empty(values.shape[:-1] + (3, 3))
    for column, targets in enumerate(pairs):
        for i, j in targets:
            out[..., i, j] = values[..., column]
    return out


def deviator(t):
    """Deviatoric part of the symmetric part of (..., 3, 3) tensors."""
    t = np.asarray(t, dtype=float)
    sym = 0.5 * (t + np.swapaxes(t, -1, -2))
    mean = np.trace(sym, axis1=-2, axis2=-1) / 3.0
    return sym - mean[..., None, None] * np.eye(3)


def von_mises_stress(stress):
    """sqrt(3/2 s:s), s the deviator of the symmetric part: equals |sigma| for uniaxial stress.
    (..., 3, 3) -> (...). Computed by the core (crystal/measures.hpp), as the run summary's
    `final_von_mises_stress` and `subslip post --quantity` are."""
    return _measure(_native.core().von_mises_stress, stress)


def von_mises_strain(strain):
    """sqrt(2/3 e:e), e the deviator of the symmetric part: equals |eps| for isochoric uniaxial
    strain (lateral -eps/2). (..., 3, 3) -> (...). As `final_von_mises_strain`."""
    return _measure(_native.core().von_mises_strain, strain)


def _measure(function, tensors):
    out = function(np.asarray(tensors, dtype=float))
    return out[()] if out.ndim == 0 else out  # one tensor: a scalar, as numpy reduces
