"""A scene as subslip._core takes it: a file's path, or a dict's YAML text and a name."""

import os

import numpy as np

from ._deps import require

# The name a scene given as a dict goes by in messages ("<scene dict>:12: law.friction.mu_s:
# ...") and in the result's /scene_file; relative paths in it (an orientation file) are relative
# to the working directory.
DICT_SCENE_NAME = "<scene dict>"


def plain(value):
    """`value` with numpy arrays and scalars turned into lists and Python numbers."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def scene_source(scene):
    """(name, YAML text) of `scene`: a path (text "": the core reads the file) or a dict."""
    if isinstance(scene, dict):
        yaml = require("yaml")
        # Block style, one key a line: the core's messages name lines of this text. Floats are
        # written as repr() writes them, which reads back to the same double.
        text = yaml.safe_dump(plain(scene), sort_keys=False, default_flow_style=None)
        return DICT_SCENE_NAME, text
    if isinstance(scene, (str, os.PathLike)):
        return os.fspath(scene), ""
    raise TypeError(f"a scene is a dict or the path of a YAML file, not {type(scene).__name__}")


def yaml_value(value):
    """`value` (a number, a list, ...) as one line of YAML in flow style, as a `--set` value."""
    yaml = require("yaml")
    text = yaml.safe_dump(plain(value), default_flow_style=True, width=float("inf"))
    return text.strip().removesuffix("...").strip()
