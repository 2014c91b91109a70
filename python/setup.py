"""Installs the subslip package with its compiled core, offline (docs/python.md):

    cmake --build build --target subslip_python      # (./build.sh run builds it too)
    pip install --no-build-isolation --no-index ./python

The core is the module CMake built (build/python/_core*.so of this source tree, or the one in
$SUBSLIP_CORE_DIR), copied into the package; nothing is compiled or downloaded here. It runs
under the interpreter it was built for (Debian's /usr/bin/python3), with Debian's numpy, h5py
and PyYAML (python3-numpy python3-h5py python3-yaml).
"""

import glob
import importlib.machinery
import os
import shutil

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

HERE = os.path.dirname(os.path.abspath(__file__))


def built_core():
    directory = os.environ.get("SUBSLIP_CORE_DIR") or os.path.join(HERE, "..", "build", "python")
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        found = glob.glob(os.path.join(directory, "_core" + suffix))
        if found:
            return found[0]
    raise SystemExit(f"subslip: no compiled core (_core) in {os.path.abspath(directory)}: build "
                     "it first (cmake --build build --target subslip_python), or set "
                     "SUBSLIP_CORE_DIR to the directory of the build's python/")


class BuildWithCore(build_py):
    """The package's Python files and the compiled core beside them."""

    def run(self):
        super().run()
        core = built_core()
        shutil.copy2(core, os.path.join(self.build_lib, "subslip", os.path.basename(core)))


class BinaryDistribution(Distribution):
    """A wheel for this interpreter and platform: it holds a compiled module."""

    def has_ext_modules(self):
        return True


setup(
    name="subslip",
    version="0.1.0",
    description="Subloading-overstress friction on contacts and crystal slip systems",
    packages=["subslip"],
    python_requires=">=3.9",
    cmdclass={"build_py": BuildWithCore},
    distclass=BinaryDistribution,
)
