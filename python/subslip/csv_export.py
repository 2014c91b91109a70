"""CSV files as `subslip post --csv` writes them (src/io/result_post.cpp), byte for byte.

One file per dataset, `<case>_<path with / as _>.csv` (characters other than letters, digits
and ._=+- become _); a header line of `name [unit]` columns; time series start with `step` and
the case's `time`; an [n, k] series has k columns named from its `layout`/`components`
attribute (a tensor's [3, 3] axes are k = 9 columns 11 12 ... 33); an [n, G, k] series is in
long format (one row per step and grain, with a `grain` column) or, with `grain`, of one grain. Only the valid rows of a series are written. Numbers
are the shortest text that reads back to the same double, in the form C++ std::to_chars
chooses (fixed or scientific, whichever is shorter: 20, 0.5, 1e-04, 1.5e+22), so that files of
both writers compare equal.
"""

import math
import os
import re

import numpy as np

from .tensors import TENSOR_CONVENTION

TENSOR_COMPONENTS = ["11", "12", "13", "21", "22", "23", "31", "32", "33"]


def shortest_digits(value):
    """(digits, point) of a finite value > 0 with value = 0.<digits> x 10^point, digits the
    shortest that round-trip (Python's repr finds them)."""
    mantissa, _, exponent = repr(value).partition("e")
    whole, _, fraction = mantissa.partition(".")
    digits = whole + fraction
    point = len(whole) + (int(exponent) if exponent else 0)
    stripped = digits.lstrip("0")
    point -= len(digits) - len(stripped)
    return stripped.rstrip("0"), point


def exact_number(value):
    """The shortest text that reads back to the same double, as std::to_chars writes it."""
    v = float(value)
    negative = math.copysign(1.0, v) < 0.0
    sign = "-" if negative else ""
    if math.isnan(v) or math.isinf(v):
        return sign + ("nan" if math.isnan(v) else "inf")
    if v == 0.0:
        return sign + "0"
    digits, point = shortest_digits(abs(v))
    return sign + min(fixed_form(abs(v), digits, point), scientific_form(digits, point),
                      key=len)


def fixed_form(value, digits, point):
    if point <= 0:
        return "0." + "0" * -point + digits
    if point >= len(digits):
        # An integer: std::to_chars writes its exact decimal value (123456789012345683968,
        # not the shortest digits padded with zeros, 123456789012345680000; same length).
        return str(int(value))
    return digits[:point] + "." + digits[point:]


def scientific_form(digits, point):
    exponent = point - 1
    mantissa = digits[0] + ("." + digits[1:] if len(digits) > 1 else "")
    return f"{mantissa}e{'-' if exponent < 0 else '+'}{abs(exponent):02d}"


def csv_field(text):
    if not any(c in text for c in ',"\n'):
        return text
    return '"' + text.replace('"', '""') + '"'


def file_safe(name):
    return re.sub(r"[^A-Za-z0-9._=+-]", "_", name)


def headed(name, unit):
    return f"{name} [{unit}]" if unit else name


def component_names(case, path, k):
    """Names of the last axis (k values), as `subslip post` derives them: slip-system labels
    for per-system data, the words of `components`/`layout` (after a ':'), the contact
    layouts, else 0..k-1."""
    d = case.dataset(path)
    if is_tensor(d):
        return list(TENSOR_COMPONENTS)
    directory = path.rpartition("/")[0]
    systems = f"{directory}/slip_systems" if directory else "slip_systems"
    for attribute in ("components", "layout"):
        if attribute not in d.attrs or not isinstance(_text(d.attrs[attribute]), str):
            continue
        text = _text(d.attrs[attribute])
        if "slip_systems" in text and systems in case:
            labels = case.dataset(systems).attrs.get("labels")
            if labels is not None and len(labels) == k:
                return [_text(x) for x in labels]
        words = text.rpartition(":")[2].split()
        if len(words) == k:
            return words
    known = {("slip", 2): ["x", "y"], ("traction", 3): ["x", "y", "n"],
             ("slip_systems", 6): ["s1", "s2", "s3", "m1", "m2", "m3"]}
    return known.get((path.rpartition("/")[2], k), [str(i) for i in range(k)])


def _text(value):
    return value.decode() if isinstance(value, bytes) else value


def is_tensor(dataset):
    """A format-3 tensor dataset: trailing axes (3, 3), components = TENSOR_CONVENTION."""
    return (dataset.ndim >= 3 and dataset.shape[-2:] == (3, 3)
            and _text(dataset.attrs.get("components", "")) == TENSOR_CONVENTION)


def table_shape(dataset, shape):
    """The shape a table sees: a tensor's two trailing axes as one of 9 components."""
    return tuple(shape[:-2]) + (9,) if is_tensor(dataset) else tuple(shape)


def time_column(case, path, rows):
    """The case's time series of `rows` valid rows: a sibling `time`, `time`, `macro/time`."""
    directory = path.rpartition("/")[0]
    for candidate in (f"{directory}/time" if directory else "time", "time", "macro/time"):
        if candidate == path or candidate not in case:
            continue
        if case.dataset(candidate).ndim == 1 and len(case.raw(candidate)) == rows:
            return candidate
    return None


def grain_times(case, path, rows):
    """A per-grain series with a sibling `row` (format 3; `row` itself too): the output rows of
    its rows and their times (macro/time at those rows), and the time unit; None otherwise."""
    directory = path.rpartition("/")[0]
    row_path = f"{directory}/row" if directory else "row"
    if directory.rpartition("/")[2] != "grains" or row_path not in case \
            or "macro/time" not in case:
        return None
    index = np.asarray(case.raw(row_path), dtype=np.int64)
    macro_time = case.raw("macro/time")
    if len(index) < rows or (len(index) and (index.min() < 0 or index.max() >= len(macro_time))):
        return None
    index = index[:rows]
    return index, macro_time[index], _text(case.dataset("macro/time").attrs.get("unit", ""))


def table_lines(case, path, grain=None):
    """The lines of one dataset's CSV (see the module text)."""
    d = case.dataset(path)
    values = case.raw(path)
    series = case.is_series(path)
    shape = table_shape(d, values.shape) or (1,)
    values = values.reshape(shape).astype(float)
    rows = shape[0]
    name = path.rpartition("/")[2]
    unit = _text(d.attrs.get("unit", ""))
    header = ["step" if series else "row"]
    per_grain = grain_times(case, path, rows) if series else None
    steps = per_grain[0] if per_grain is not None else None
    if per_grain is not None:  # the steps are the output rows these per-grain rows are at
        time = per_grain[1]
        header.append(csv_field(headed("time", per_grain[2])))
    else:
        time_path = time_column(case, path, rows) if series else None
        time = case.raw(time_path) if time_path else None
        if time is not None:
            header.append(csv_field(headed("time", _text(case.dataset(time_path).attrs.get(
                "unit", "")))))
    labels = [_text(x) for x in d.attrs.get("labels", [])] if not series else []
    if len(labels) != rows:
        labels = []
    if labels:
        header[0] = "label"
    long_format = len(shape) == 3 and grain is None
    if long_format:
        header.append("grain")
    if len(shape) == 1:
        header.append(csv_field(headed(name, unit)))
    else:
        header += [csv_field(headed(f"{name}_{c}", unit))
                   for c in component_names(case, path, shape[-1])]
    yield ",".join(header)
    for row in range(rows):
        start = [csv_field(labels[row]) if labels
                 else str(int(steps[row])) if steps is not None else str(row)]
        if time is not None:
            start.append(exact_number(time[row]))
        per_grain = values[row].reshape(-1, shape[-1] if len(shape) > 1 else 1)
        for g in ([grain] if grain is not None and len(shape) == 3 else range(len(per_grain))):
            fields = start + ([str(g)] if long_format else [])
            yield ",".join(fields + [exact_number(x) for x in per_grain[g]])


def requested_paths(case, names):
    """Dataset paths of `names` (datasets or groups; None: every dataset), numeric only;
    text named explicitly is an error, as in `subslip post`."""
    if names is None:
        return [p for p in case.datasets() if _numeric(case, p)]
    paths = []
    for name in [names] if isinstance(names, str) else names:
        if name in case:
            if not _numeric(case, name):
                raise ValueError(f"case '{case.name}': '{name}' holds text, not numbers")
            paths.append(name)
        elif case.group is not None and name in case.group:
            paths += [p for p in case.datasets(name) if _numeric(case, p)]
        else:
            raise KeyError(f"no dataset '{name}' in case '{case.name}'; it has: "
                           + ", ".join(case.datasets()))
    return list(dict.fromkeys(paths))


def _numeric(case, path):
    return case.dataset(path).dtype.kind in "fiu"


def export_case(case, directory, names=None, grain=None, overwrite=False):
    """Writes the CSV files of `names` of `case` into `directory`; returns their paths. Every
    name and target is checked before anything is written."""
    plan, used = [], set()
    for path in requested_paths(case, names):
        d = case.dataset(path)
        ndim = len(table_shape(d, d.shape))  # (a tensor's 3x3 counted as one axis)
        if ndim > 3:
            raise ValueError(f"'{path}' has rank {ndim}; only ranks 0 to 3 (and tensors of rank "
                             "3 and 4) are exported")
        one_grain = grain if ndim == 3 else None
        grains = d.shape[1] if ndim == 3 else 0
        if one_grain is not None and not 0 <= one_grain < grains:
            raise IndexError(f"grain {grain} is out of range: '{path}' has {grains} grains")
        stem = f"{file_safe(case.name)}_{file_safe(path.replace('/', '_'))}"
        stem += f"_grain{grain}" if one_grain is not None else ""
        target, n = f"{stem}.csv", 2
        while target in used:  # two names made the same by file_safe
            target, n = f"{stem}_{n}.csv", n + 1
        used.add(target)
        plan.append((path, one_grain, os.path.join(directory, target)))
    for _, _, target in plan:
        if os.path.exists(target) and not overwrite:
            raise FileExistsError(f"{target}: already exists; pass overwrite=True")
    os.makedirs(directory, exist_ok=True)
    for path, one_grain, target in plan:
        with open(target, "w", encoding="utf-8", newline="\n") as out:
            for line in table_lines(case, path, one_grain):
                out.write(line + "\n")
    return [target for _, _, target in plan]
