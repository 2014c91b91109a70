#!/usr/bin/python3
"""Mixed control's cost against L prescribed, and the floor no two-sweep scheme goes below.

    /usr/bin/python3 bench/mixed_control_floor.py [--subslip build/src/subslip]
                     [--scene inputs/default.yaml] [--workdir DIR] [--stress-tolerance T]
                     [--profiles PRESCRIBED MIXED]

Valgrind runs no AVX-512: on such a machine give it a subslip configured with
-DSUBSLIP_GRAIN_STEP_ISA=all (docs/build.md). Runs the scene twice under valgrind's callgrind,
one thread: as it is (mixed control: L33
prescribed, the lateral and shear stresses held) and with its velocity gradient fully
prescribed (L = diag(-1/2, -1/2, 1) L33, no stress condition: the same grains, increments and
tolerances). From the two profiles it prints, in instructions per grain and increment:

* E, one evaluation of a grain's flow rules (StressSolver::evaluate_slips, inclusive);
* K, a grain's kinematics and end state at a given L (step_kinematics, the orientation after
  the plastic spin, the sample stress);
* T, a grain's consistent tangent (slip_sensitivities with its condensation, sample_tangent);

and the floors of docs/benchmarks.md ("A floor for any scheme that verifies each grain at the
final L"): with the free stresses' tolerance below what a predictor reaches, every increment
solves each grain at a trial L and again at the final L, and the solve at the final L needs at
least one evaluation and the kinematics there. So mixed control costs at least
1 + (E + K) / P of the prescribed run (P per grain and increment), and 1 + (E + K + T) / P when
the Jacobian of the free stresses comes from the grains' tangents (which also carry each grain's
slips to the final L, so that one evaluation verifies it). With --stress-tolerance it also runs
the scene (without valgrind, h5py needed) at that tolerance, as it is and with its increments
halved, and prints how far the macro sigma_33 moves with the tolerance against how far it moves
with the increments.

Needs valgrind (Debian: apt-get install valgrind); about 3 minutes on a 2-core machine.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile

# What each quantity sums (function names as callgrind_annotate prints them, templates matched
# for any slip count).
# Anchored at the start: a name can stand again inside another's template arguments.
RETURNS = r"^(?:[\w:]+(?:<[^>]*>)? )?subslip::crystal::"
EVALUATION = [RETURNS + r"implicit_detail::StressSolver<\d+>::evaluate_slips\("]
KINEMATICS = [RETURNS + r"detail::step_kinematics\(",
              RETURNS + r"detail::orientation_after_plastic_spin<\d+>\(",
              RETURNS + r"GrainState<\d+>::sample_stress\(\)"]
TANGENT = [RETURNS + r"implicit_detail::StressSolver<\d+>::slip_sensitivities\(",
           RETURNS + r"detail::sample_tangent<\d+>\("]
GRAIN_SOLVE = [RETURNS + r"solve_grain_step<\d+>\("]

MIXED_L = "  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]\n"
MIXED_STRESS = "    stress: [[0, x, x], [x, 0, x], [x, x, x]]\n"
PRESCRIBED_L = "  - L: [[-0.5e-3, 0, 0], [0, -0.5e-3, 0], [0, 0, 1.0e-3]]\n"


def with_absolute_files(text, scene_path):
    """The scene's text with its files (orientations) named from its own directory."""
    scene_dir = os.path.dirname(os.path.abspath(scene_path))
    return re.sub(r"(\n\s*file:\s*)(\S+)",
                  lambda m: m.group(1) + os.path.normpath(os.path.join(scene_dir, m.group(2))),
                  text)


def scene_variants(scene_path, workdir, stress_tolerance):
    """The scene as it is and with L prescribed, orientation files made absolute (and its
    free-stress tolerance replaced, if one is given)."""
    with open(scene_path) as f:
        text = f.read()
    if stress_tolerance is not None:
        text, count = re.subn(r"stress_tolerance:\s*[^,}\s]+",
                              f"stress_tolerance: {stress_tolerance:g}", text)
        if count != 1:
            sys.exit(f"{scene_path}: expected one integrator key stress_tolerance to replace")
    if MIXED_L + MIXED_STRESS not in text:
        sys.exit(f"{scene_path}: expected the default scene's loading lines\n"
                 f"{MIXED_L}{MIXED_STRESS}"
                 "(this script compares that scene's mixed control with its L prescribed)")
    text = with_absolute_files(text, scene_path)
    paths = {}
    for name, body in (("mixed", text), ("prescribed", text.replace(MIXED_L + MIXED_STRESS,
                                                                     PRESCRIBED_L))):
        paths[name] = os.path.join(workdir, name + ".yaml")
        with open(paths[name], "w") as f:
            f.write(body)
    return paths


def profile(subslip, scene, workdir, name):
    out = os.path.join(workdir, "callgrind." + name)
    cmd = ["valgrind", "--tool=callgrind", "--callgrind-out-file=" + out, subslip, "run", scene,
           "-o", os.path.join(workdir, name + ".h5"), "--force", "-j", "1"]
    print("running:", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return annotated(out)


def annotated(profile_path):
    tree = subprocess.run(["callgrind_annotate", "--tree=caller", "--inclusive=yes", profile_path],
                          check=True, capture_output=True, text=True).stdout
    return parse_tree(tree)


def parse_tree(tree):
    """Inclusive instructions and calls of every function, and the program total."""
    functions, total = {}, None
    callers = 0
    for line in tree.splitlines():
        m = re.match(r"\s*([\d,]+)\s+(?:\([^)]*\)\s+)?PROGRAM TOTALS", line)
        if m:
            total = int(m.group(1).replace(",", ""))
            continue
        m = re.match(r"\s*([\d,]+)\s+\([^)]*\)\s+([<*>])\s+\S*?:(.*)$", line)
        if not m:
            callers = 0
            continue
        cost, kind, rest = int(m.group(1).replace(",", "")), m.group(2), m.group(3)
        calls = re.search(r"\((\d[\d,]*)x\)", rest)
        if kind == "<":
            callers += int(calls.group(1).replace(",", "")) if calls else 0
        elif kind == "*":
            functions[rest] = (cost, callers)
            callers = 0
    if total is None:
        sys.exit("callgrind_annotate printed no program total")
    return total, functions


def summed(functions, patterns):
    """Inclusive instructions and calls of the functions matching each pattern (calls of the
    first)."""
    cost, calls = 0, None
    for pattern in patterns:
        hits = [v for k, v in functions.items() if re.search(pattern, k)]
        if not hits:
            sys.exit(f"no function matches {pattern} (a changed name? update this script)")
        cost += sum(c for c, _ in hits)
        if calls is None:
            calls = sum(n for _, n in hits)
    return cost, calls


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--subslip", default="build/src/subslip")
    parser.add_argument("--scene", default="inputs/default.yaml")
    parser.add_argument("--workdir", help="keep the scenes, outputs and profiles here")
    parser.add_argument("--stress-tolerance", type=float,
                        help="mixed control's free-stress tolerance instead of the scene's")
    parser.add_argument("--profiles", nargs=2, metavar=("PRESCRIBED", "MIXED"),
                        help="read these callgrind profiles of the two runs instead of running")
    args = parser.parse_args()
    for tool in ("callgrind_annotate",) if args.profiles else ("valgrind", "callgrind_annotate"):
        if shutil.which(tool) is None:
            sys.exit(f"{tool} not found (Debian: apt-get install valgrind)")
    if args.profiles:
        workdir = os.path.dirname(os.path.abspath(args.profiles[0]))
        runs = dict(zip(("prescribed", "mixed"), map(annotated, args.profiles)))
    else:
        subslip = os.path.abspath(args.subslip)
        workdir = args.workdir or tempfile.mkdtemp(prefix="subslip_floor_")
        os.makedirs(workdir, exist_ok=True)
        scenes = scene_variants(args.scene, workdir, args.stress_tolerance)
        runs = {name: profile(subslip, scenes[name], workdir, name)
                for name in ("prescribed", "mixed")}

    (p_total, p_fn), (m_total, m_fn) = runs["prescribed"], runs["mixed"]
    increments = summed(p_fn, GRAIN_SOLVE)[1]  # grain solves of the prescribed run
    m_solves = summed(m_fn, GRAIN_SOLVE)[1]
    e_cost, e_calls = summed(m_fn, EVALUATION)
    evaluation = e_cost / e_calls
    kinematics = sum(c / n for c, n in (summed(m_fn, [p]) for p in KINEMATICS))
    tangent = summed(m_fn, TANGENT)[0] / increments
    per = p_total / increments

    tolerance = ("" if args.stress_tolerance is None
                 else f", stress_tolerance {args.stress_tolerance:g}")
    print(f"\nscene {args.scene}{tolerance}, one thread; instructions (callgrind), profiles in "
          f"{workdir}")
    print(f"L prescribed : {p_total:.4e}  ({increments} grain solves, {per:.4g} per grain and"
          " increment)")
    print(f"mixed control: {m_total:.4e}  ({m_solves} grain solves, "
          f"{m_solves / increments:.3f} per grain and increment)   ratio {m_total / p_total:.3f}")
    print(f"E  one evaluation of a grain's flow rules      {evaluation:8.0f}  ({e_calls} in the"
          " mixed run)")
    print(f"K  a grain's kinematics and end state at an L  {kinematics:8.0f}")
    print(f"T  a grain's consistent tangent                {tangent:8.0f}")
    print("floors with a second solve of every grain in every increment (a tolerance no predictor"
          " meets):")
    print(f"floor, Jacobian free of cost:       1 + (E + K) / P     = "
          f"{1 + (evaluation + kinematics) / per:.3f}")
    print(f"floor, Jacobian from the tangents:  1 + (E + K + T) / P = "
          f"{1 + (evaluation + kinematics + tangent) / per:.3f}")
    print(f"measured:                                              "
          f"{m_total / p_total:.3f}")
    if args.stress_tolerance is not None and not args.profiles:
        free_stress_error(subslip, args.scene, workdir, scenes["mixed"])


def axial_stress(subslip, scene, out):
    """Time and sigma_33 [MPa] of the macro output of a run of `scene`."""
    import h5py  # only here: the profiles need no h5py
    import numpy
    subprocess.run([subslip, "run", scene, "-o", out, "--force"], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with h5py.File(out, "r") as f:
        macro = f["cases/base/macro"]
        return numpy.asarray(macro["time"]), numpy.asarray(macro["stress"])[:, 2, 2]


def free_stress_error(subslip, scene_path, workdir, loose_scene):
    """What the looser tolerance costs the main job's output, against what its increments do:
    sigma_33 over the path at that tolerance and with the increments halved, each against the
    scene as it is, relative to the largest |sigma_33|."""
    with open(scene_path) as f:
        text = f.read()
    text = with_absolute_files(text, scene_path)
    halved, count = re.subn(r"increments:\s*(\d+)", lambda m: f"increments: {2 * int(m.group(1))}",
                            text)
    if count != 1:
        sys.exit(f"{scene_path}: expected one loading segment with its increments")
    paths = {}
    for name, body in (("as_given", text), ("halved", halved)):
        paths[name] = os.path.join(workdir, name + ".yaml")
        with open(paths[name], "w") as f:
            f.write(body)
    t, reference = axial_stress(subslip, paths["as_given"], os.path.join(workdir, "as_given.h5"))
    _, loose = axial_stress(subslip, loose_scene, os.path.join(workdir, "loose.h5"))
    t_fine, fine = axial_stress(subslip, paths["halved"], os.path.join(workdir, "halved.h5"))
    at_coarse = [min(range(len(t_fine)), key=lambda i: abs(t_fine[i] - x)) for x in t]
    scale = abs(reference).max()
    print(f"macro sigma_33 (largest {scale:.4g} MPa), largest difference over the path, relative:")
    print(f"  at this tolerance against the scene's:     "
          f"{abs(loose - reference).max() / scale:.3g}")
    print(f"  increments halved against the scene's:     "
          f"{abs(fine[at_coarse] - reference).max() / scale:.3g}  (backward Euler's error is"
          " about twice this)")


if __name__ == "__main__":
    main()
