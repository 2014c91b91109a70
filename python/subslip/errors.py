"""The errors of subslip.run and of the material points (subslip._core raises them).

They live here, not in the compiled module, so that `except subslip.SceneError` works where the
module is not built.
"""


class SceneError(ValueError):
    """Bad input: a scene (or its orientation file, or an output path) the command line would
    refuse with exit status 2. The message is the command line's: file, line and key."""


class StepFailure(RuntimeError):
    """A contact or grain step that cannot be completed (the command line's exit status 3)."""


class RunError(RuntimeError):
    """Any other failure of a run (writing the result file, ...: exit status 1)."""


class MissingCore(ImportError):
    """The compiled module subslip._core is not built or not installed."""


class SceneWarning(UserWarning):
    """A scene setting that is legal but suspicious (the command line prints it as a warning)."""


class FitWarning(UserWarning):
    """A constant a fit leaves undetermined, and which data would determine it (`subslip fit`
    prints the same warning)."""
