"""Imports of the third-party modules subslip needs, failing with what to install.

A missing module otherwise ends in a bare "No module named 'h5py'" traceback, which does not say
that Debian packages them (python3-h5py, ...) for /usr/bin/python3 only, not for a python3 that
comes first on PATH (a virtualenv, conda).
"""

import importlib
import sys

# module name -> Debian package that provides it for /usr/bin/python3
DEBIAN_PACKAGES = {
    "numpy": "python3-numpy",
    "h5py": "python3-h5py",
    "matplotlib": "python3-matplotlib",
    "yaml": "python3-yaml",
}


class MissingDependency(ImportError):
    """A module subslip needs is not importable; the message says what to install."""


DEBIAN_PYTHON = "/usr/bin/python3"


def install_hint(modules):
    """The sentence naming the Debian packages of `modules` (and the interpreter to use)."""
    packages = " ".join(DEBIAN_PACKAGES.get(m, m) for m in modules)
    hint = f"install it with `apt-get install {packages}`"
    if sys.executable != DEBIAN_PYTHON:
        hint += (f" and run {DEBIAN_PYTHON} (this is {sys.executable}, which does not see "
                 "Debian's python3-* packages)")
    return hint


def require(module, purpose="subslip"):
    """Imports `module`, or raises MissingDependency naming the package to install."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise MissingDependency(f"{purpose} needs the Python module {module} ({e}); "
                                + install_hint([module])) from None
