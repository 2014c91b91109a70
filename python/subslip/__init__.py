"""subslip: running scenes and material points of the core, reading result files (HDF5).

    import subslip
    result = subslip.run("inputs/default.yaml")      # a dict or a YAML file; in memory
    with subslip.open("results/default.h5") as result:
        case = result.case(result.cases[0])
        stress = case.series("macro/stress")        # (n, 3, 3), valid rows only
        print(case.unit("macro/stress"), subslip.von_mises_stress(stress[-1]))

Series are cut to the rows the run wrote (/progress), tensors come as (n, 3, 3) or
(n, G, 3, 3) whatever the file's column layout, and derived quantities (von Mises measures,
equivalent plastic strain, slip activity, pole-figure and inverse-pole-figure points) and CSV
export are on the Case. subslip.run, ContactPoint, GrainPoint and TaylorPoint call the compiled
core (subslip._core, built by ./build.sh run). Needs numpy and h5py (Debian: apt-get install
python3-numpy python3-h5py; use /usr/bin/python3), for a scene given as a dict PyYAML
(python3-yaml). Tutorial: docs/python.md.
"""

from ._deps import MissingDependency, require

require("numpy")
require("h5py")

from .result import CASE_STATES, Case, MissingData, NotAResult, Result, open  # noqa: E402
from .tensors import (LayoutError, to_matrices, von_mises_strain,  # noqa: E402
                      von_mises_stress)
from .texture import (cubic_family, hexagonal_family, inverse_pole_figure_points,  # noqa: E402
                      pole_families, pole_figure_points, quaternion_to_matrix)
from .derived import loading_component  # noqa: E402
from .csv_export import MissingBinary, exact_number  # noqa: E402
from .errors import (FitWarning, MissingCore, RunError, SceneError, SceneWarning,  # noqa: E402
                     StepFailure)
from .run import run  # noqa: E402
from .point import ContactPoint, GrainPoint, TaylorPoint, increment_lengths  # noqa: E402
from .calibration import fit, fit_figure  # noqa: E402

__all__ = [
    "open", "Result", "Case", "CASE_STATES", "NotAResult", "MissingData", "MissingDependency",
    "LayoutError", "to_matrices", "von_mises_stress", "von_mises_strain", "quaternion_to_matrix",
    "cubic_family", "hexagonal_family", "pole_families", "pole_figure_points",
    "inverse_pole_figure_points", "loading_component", "exact_number", "MissingBinary",
    "run", "ContactPoint", "GrainPoint", "TaylorPoint", "increment_lengths", "SceneError",
    "StepFailure", "RunError", "SceneWarning", "MissingCore", "fit", "fit_figure", "FitWarning",
]
