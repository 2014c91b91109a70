"""The compiled core, subslip._core (src/python/module.cpp), loaded when first used.

An installed package (pip install ./python) has it beside this file. In a source tree it is
where CMake writes it, build/python/ (./build.sh run builds it); $SUBSLIP_CORE_DIR names the
directory of another build. Reading result files needs none of it.
"""

import importlib
import importlib.machinery
import importlib.util
import os
import sys

from .errors import MissingCore

_SOURCE_TREE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _candidates():
    given = os.environ.get("SUBSLIP_CORE_DIR")
    dirs = [given] if given else [os.path.join(_SOURCE_TREE, "build", "python")]
    for d in dirs:
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = os.path.join(d, "_core" + suffix)
            if os.path.isfile(path):
                yield path


def core():
    """The module subslip._core; MissingCore says how to build it."""
    name = __package__ + "._core"
    if name in sys.modules:
        return sys.modules[name]
    try:
        return importlib.import_module(name)  # installed beside the package
    except ModuleNotFoundError:
        pass
    for path in _candidates():
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        try:
            spec.loader.exec_module(module)
        except ImportError as e:
            del sys.modules[name]
            raise MissingCore(f"{path}: cannot be loaded ({e}); rebuild it with "
                              "`cmake --build build --target subslip_python` for "
                              f"{sys.executable}") from e
        return module
    where = os.environ.get("SUBSLIP_CORE_DIR") or os.path.join(_SOURCE_TREE, "build", "python")
    raise MissingCore(f"subslip's compiled core (_core) is neither installed nor in {where}: "
                      "build it with ./build.sh run (or cmake --build build --target "
                      "subslip_python), or install the package (docs/python.md)")
