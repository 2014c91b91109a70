"""CSV files of a case: `subslip post --csv` (src/io/result_csv.cpp) is the one CSV writer, and
`Case.to_csv` and `Case.to_table` run it (the command line must export without Python, and one
writer cannot disagree with itself). The files are described in docs/python.md and docs/scenes.md: one per
dataset, `<case>_<path>.csv`, a header of `name [unit]` columns, the valid rows only, numbers as
the shortest text that reads back to the same double.

The binary is $SUBSLIP_BINARY, else build/src/subslip of the source tree this package is in,
else `subslip` on PATH. `exact_number` gives the text the files hold for one number (the form
std::to_chars chooses: 20, 0.5, 1e-04, 1.5e+22), to check values against them.
"""

import builtins
import math
import os
import shutil
import subprocess
import tempfile


class MissingBinary(RuntimeError):
    """CSV export needs the subslip program, and none was found."""


def subslip_binary():
    """The subslip program CSV export runs (see the module text), or None."""
    given = os.environ.get("SUBSLIP_BINARY")
    if given:
        return given
    source = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    built = os.path.join(source, "build", "src", "subslip")
    if os.access(built, os.X_OK):
        return built
    return shutil.which("subslip")


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


def _error(message):
    """The exception of `subslip post`'s message, as the Python caller expects it."""
    if "already exists" in message:
        return FileExistsError(message)
    if "out of range" in message:
        return IndexError(message)
    if "no dataset" in message or "no quantity" in message:
        return KeyError(message)
    return ValueError(message)  # text named explicitly, rank > 3, ...


def export_case(case, directory, names=None, grain=None, overwrite=False, quantities=None):
    """Writes the CSV files of `names` (dataset or group paths of `case`; None: every numeric
    dataset) into `directory` with `subslip post --csv`, or with `quantities` the case's one
    table of them (`--quantity`); returns their paths. Every name and target is checked before
    anything is written."""
    binary = subslip_binary()
    if not binary:
        raise MissingBinary("CSV export runs `subslip post --csv`: build subslip (./build.sh) "
                            "or set SUBSLIP_BINARY to the program")
    if case.group is None:  # listed but never created: nothing to write
        return []
    if case.result.image is not None:  # a result in memory (subslip.run): post reads a copy
        with tempfile.TemporaryDirectory(prefix="subslip-") as copy:
            path = os.path.join(copy, "result.h5")
            with builtins.open(path, "wb") as f:
                f.write(case.result.image)
            return _post_csv(binary, path, case, directory, names, grain, overwrite,
                             quantities)
    return _post_csv(binary, case.result.path, case, directory, names, grain, overwrite,
                     quantities)


def _post_csv(binary, path, case, directory, names, grain, overwrite, quantities=None):
    command = [binary, "post", path, "--csv", os.fspath(directory), "--case", case.name]
    for name in [names] if isinstance(names, str) else (names or []):
        command += ["--dataset", name]
    for name in [quantities] if isinstance(quantities, str) else (quantities or []):
        command += ["--quantity", name]
    if grain is not None:
        command += ["--grain", str(grain)]
    if overwrite:
        command.append("--force")
    try:
        done = subprocess.run(command, capture_output=True, text=True)
    except OSError as e:  # $SUBSLIP_BINARY names no program
        raise MissingBinary(f"CSV export runs `subslip post --csv`: {binary}: {e.strerror}") from e
    if done.returncode != 0:
        lines = [l for l in done.stderr.splitlines() if l.strip()]
        raise _error("\n".join(lines) or f"subslip post exited with {done.returncode}")
    return [line for line in done.stdout.splitlines() if line]
