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
}


class MissingDependency(ImportError):
    """A module subslip needs is not importable; the message says what to install."""


def install_hint(modules):
    """The sentence naming the Debian packages of `modules` (and the interpreter to use)."""
    packages = " ".join(DEBIAN_PACKAGES.get(m, m) for m in modules)
    return (f"install it with `apt-get install {packages}` and run /usr/bin/python3 "
            f"(Debian's packages are not seen by other interpreters; this is {sys.executable})")


def require(module, purpose="subslip"):
    """Imports `module`, or raises MissingDependency naming the package to install."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise MissingDependency(f"{purpose} needs the Python module {module} ({e}); "
                                + install_hint([module])) from None
