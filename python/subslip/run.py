"""subslip.run: a scene run as `subslip run` runs it, its result in memory or in a file."""

import builtins
import os
import tempfile
import warnings

from ._native import core
from .errors import RunError, SceneError, SceneWarning, StepFailure
from .result import Result
from .scene_source import scene_source, yaml_value

# The command line's exit statuses (src/cli/run_scene.hpp) and the errors they become.
_ERRORS = {2: SceneError, 3: StepFailure}


def _run(name, text, output, force, threads, settings):
    code, message, scene_warnings = core().run_scene(name, text, output, force, threads,
                                                     settings)
    for w in scene_warnings:
        warnings.warn(w, SceneWarning, stacklevel=3)
    if code != 0:
        raise _ERRORS.get(code, RunError)(message)


def _settings(overrides):
    """{path: value} as the command line's `--set PATH=VALUE` arguments, in order: a string
    value as written (`"1 mm/min"`), any other as YAML in flow style (numbers as `repr`
    writes them, so the same doubles)."""
    settings = []
    for path, value in (overrides or {}).items():
        if not isinstance(value, str):
            value = yaml_value(value)
        settings.append(f"{path}={value}")
    return settings


def run(scene, output=None, *, force=False, threads=0, overrides=None):
    """Runs `scene` (a dict, or the path of a YAML file) as `build/src/subslip run` does and
    returns its result, the object subslip.open returns for a file.

    `overrides` ({"loading[0].increments": 400, "phase.tau0": "12 MPa"}) are the command
    line's `--set` settings: each value set over the scene's at its key path, checked as the
    scene's own and recorded in the result file.

    Without `output` the result is held in memory: the run writes its file into a temporary
    directory, which is read and removed before this returns. With `output` the result file is
    written there (an existing one only with force=True) and opened from it. `threads`: OpenMP
    threads (0: OpenMP's default). The Python interpreter keeps running while the core computes
    (other threads can work); runs in one process take turns.

    Raises SceneError (a ValueError) with the command line's message for bad input, StepFailure
    when a step cannot be completed, RunError for other failures; the scene's warnings become
    SceneWarning warnings.
    """
    name, text = scene_source(scene)
    settings = _settings(overrides)
    if threads < 0:
        raise ValueError(f"threads = {threads}: 0 (OpenMP's default) or more")
    if output is not None:
        _run(name, text, os.fspath(output), force, threads, settings)
        return Result(output)
    with tempfile.TemporaryDirectory(prefix="subslip-run-") as directory:
        path = os.path.join(directory, "result.h5")
        _run(name, text, path, False, threads, settings)
        with builtins.open(path, "rb") as f:
            image = f.read()
    return Result(f"{name} (in memory)", image=image)
