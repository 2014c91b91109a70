#!/usr/bin/python3
"""Writes the synthetic single-crystal curves of inputs/crystal_fit_three_orientations.yaml:
inputs/fit_curves/crystal_001.csv, crystal_111.csv and crystal_m123.csv.

    SUBSLIP_CORE_DIR=build/python /usr/bin/python3 scripts/make_crystal_fit_curves.py

Each curve is subslip's own model of the crystal fit (subslip._core.crystal_fit_predict, the C++
calibration::predict that `subslip fit` fits with): one grain of the copper phase of
inputs/fcc_single_crystal_tension_001.yaml (the constants the fit is to recover) pulled along
sample x at 1e-3 /s with sigma22 = sigma33 = 0 and no shear, with crystal [001], [111] and
[-1 2 3] along x. Its sigma11 [MPa] at 60 logarithmic strains from 0.002 to 0.3 (evenly in log)
gets 1 % Gaussian noise (seed 2016). The path takes 600 equal steps, twice the fit file's, so that
the data are the model's with a smaller step error than the fit's own evaluation of it. Needs the Python module built (build/python) and numpy.
"""

import os
import random
import sys

import numpy as np

SOURCE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, os.path.join(SOURCE, "python"))

from subslip._native import core  # noqa: E402

# The phase whose constants make the curves (its orientation file is not used here).
SCENE = os.path.join(SOURCE, "inputs", "fcc_single_crystal_tension_001.yaml")
STRAIN_RATE = 1.0e-3  # [1/s]
SEED = 2016
# (file, crystal direction along sample x, Bunge Euler angles [deg]). phi1 = 90 deg puts the
# direction d along x with sin(Phi) = d3 and phi2 = atan2(-d1, -d2) (checked below).
CURVES = [
    ("crystal_001.csv", (0, 0, 1), (90.0, 90.0, 0.0)),
    ("crystal_111.csv", (1, 1, 1), (90.0, 35.2643897, 225.0)),
    ("crystal_m123.csv", (-1, 2, 3), (90.0, 53.3007748, 153.4349488)),
]


def orientation_matrix(euler_deg):
    """g of Bunge Euler angles (v_crystal = g v_sample), as crystal::euler_to_matrix."""
    p1, big_phi, p2 = np.radians(euler_deg)
    c1, s1, c, s = np.cos(p1), np.sin(p1), np.cos(big_phi), np.sin(big_phi)
    c2, s2 = np.cos(p2), np.sin(p2)
    return np.array([[c1 * c2 - s1 * s2 * c, s1 * c2 + c1 * s2 * c, s2 * s],
                     [-c1 * s2 - s1 * c2 * c, -s1 * s2 + c1 * c2 * c, c2 * s],
                     [s1 * s, -c1 * s, c]])


def main():
    strains = 0.002 * (0.3 / 0.002) ** (np.arange(60) / 59.0)
    noise = random.Random(SEED)
    with open(SCENE, encoding="utf-8") as f:
        scene_text = f.read()
    for name, direction, euler in CURVES:
        d = np.array(direction, float) / np.linalg.norm(direction)
        along_x = orientation_matrix(euler)[:, 0]  # the crystal direction of sample x
        if np.linalg.norm(along_x - d) > 1e-7:
            raise SystemExit(f"{name}: the Euler angles {euler} put {along_x} along x, not {d}")
        stress = core().crystal_fit_predict(SCENE, scene_text, "", list(euler), STRAIN_RATE,
                                            strains, 600)
        path = os.path.join(SOURCE, "inputs", "fit_curves", name)
        label = "[" + " ".join(str(k) for k in direction) + "]"
        with open(path, "w", encoding="utf-8") as out:
            angles = ", ".join(f"{a:g}" for a in euler)
            out.write(f"# Synthetic tension curve of copper, crystal {label} along x (Bunge Euler\n"
                      f"# angles {angles} deg) at 1e-3 /s: the phase of\n"
                      "# inputs/fcc_single_crystal_tension_001.yaml computed by subslip\n"
                      "# (scripts/make_crystal_fit_curves.py), sigma11 with 1 % Gaussian noise "
                      f"(seed {SEED}).\n")
            out.write("strain [-], stress [MPa]\n")
            for e, s in zip(strains, stress):
                out.write(f"{e:.6g}, {s * (1.0 + noise.gauss(0.0, 0.01)):.6g}\n")
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
