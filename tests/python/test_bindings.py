"""The Python bindings of the core (subslip._core, src/python/module.cpp; docs/python.md).

    SUBSLIP_BINARY=build/src/subslip SUBSLIP_CORE_DIR=build/python PYTHONPATH=python \
        /usr/bin/python3 -m unittest tests/python/test_bindings.py -v

* subslip.run gives the command line's result file: every numeric dataset bitwise, for the main
  job, a contact scene and a sweep; a scene given as a dict gives the file of the same scene;
* the core computes without the GIL; four Python threads running scenes, and material points,
  at once get identical results;
* a bad scene raises SceneError with the message the command line prints, and the interpreter
  goes on;
* a contact point, a grain and a Taylor point driven along a scene's steps give the driver's
  rows bitwise (the file's traction, mu, r_s, slip; macro and grain stress);
* subslip.fit gives `subslip fit --json`'s report and its error messages, and draws the figure,
  for a friction fit and a crystal fit;
* the package installs offline (pip, no index, no build isolation) and runs from there.
"""

import copy
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import unittest
import warnings

import h5py
import numpy as np
import yaml

import subslip

SOURCE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BINARY = os.environ.get("SUBSLIP_BINARY", os.path.join(SOURCE, "build", "src", "subslip"))


def scene_path(*parts):
    return os.path.join(SOURCE, *parts)


def numeric_datasets(f):
    """{path: array} of every numeric dataset of an open h5py file."""
    found = {}

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset) and obj.dtype.kind in "fiuc":
            found[name] = obj[()]

    f.visititems(visit)
    return found


def text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def cli_run(scene, directory):
    """Runs `subslip run` into directory/cli.h5: (exit status, stderr, path)."""
    out = os.path.join(directory, "cli.h5")
    done = subprocess.run([BINARY, "run", scene, "-o", out, "-q"], capture_output=True,
                          text=True, cwd=SOURCE)
    return done.returncode, done.stderr, out


# A small Taylor aggregate along tension, simple shear and compression (increments growing in
# the shear): active sets change and the slip rates turn.
TAYLOR_SCENE = {
    "scene": "crystal",
    "units": {"stress": "MPa", "time": "s"},
    "phase": {
        "families": ["fcc_111_110"],
        "elasticity": {"type": "cubic", "C11": 168400, "C12": 121400, "C44": 75400},
        "tau0": 10.0,
        "law": {
            "friction": {"mu_s": 1.0, "mu_k": 3.0, "kappa": 5.0, "xi": 0.0},
            "subloading": {"function": "cot", "u_tilde": 200},
            "overstress": {"form": "exponential", "eta_v": 1.0e-3, "n": 16, "r_hat": 1.6},
        },
        "kinematics": "finite_rotation",
    },
    "orientations": {"euler_deg": [[17.0, 11.0, 63.0], [57.0, 32.0, 126.0], [97.0, 53.0, 189.0],
                                   [137.0, 74.0, 252.0], [177.0, 95.0, 315.0]]},
    "loading": [
        {"L": [[-0.5e-3, 0, 0], [0, -0.5e-3, 0], [0, 0, 1.0e-3]], "duration": 5.0,
         "increments": 25},
        {"L": [[0, 2.0e-3, 0], [0, 0, 0], [0, 0, 0]], "duration": 2.0, "increments": 20,
         "growth": 1.1},
        {"L": [[0.5e-3, 0, 0], [0, 0.5e-3, 0], [0, 0, -1.0e-3]], "duration": 4.0,
         "increments": 16},
    ],
    "output": {"macro": ["time", "stress"], "grains": ["stress", "slip"]},
}

# Slide, reverse, hold, re-slide: every branch of the contact update.
CONTACT_SCENE = {
    "scene": "contact",
    "units": {"stress": "MPa", "length": "mm", "time": "s"},
    "law": {
        "friction": {"mu_s": 0.097, "mu_k": 0.085, "kappa": 0.2, "xi": 0.05},
        "subloading": {"function": "cot", "u_tilde": 80},
        "overstress": {"form": "exponential", "eta_v": 950, "n": 16, "r_hat": 1.8},
    },
    "contact": {"alpha_n": 1.0e6, "alpha_t": 1.0e6, "normal_traction": 5.56},
    "loading": [
        {"slide": {"speed": 0.01, "direction": [1, 0], "distance": 0.1}, "increments": 200,
         "growth": 1.01},
        {"slide": {"speed": 0.02, "direction": [-1, 0.5], "distance": 0.05}, "increments": 100},
        {"hold": {"duration": 60}, "increments": 50, "growth": 1.05},
        {"slide": {"speed": 0.01, "direction": [1, 0], "distance": 0.1}, "increments": 200},
    ],
    "output": {"fields": ["time", "slip", "traction", "ratio", "mu", "r", "r_s", "vp_slip"]},
}


class RunEqualsTheCommandLine(unittest.TestCase):
    def assert_bitwise(self, expected, got, what):
        self.assertEqual(sorted(expected), sorted(got), what)
        for name, a in expected.items():
            b = got[name]
            self.assertEqual((a.dtype, a.shape), (b.dtype, b.shape), f"{what}: {name}")
            self.assertEqual(a.tobytes(), b.tobytes(), f"{what}: {name} differs")

    def check_scene(self, relative):
        scene = scene_path(relative)
        with tempfile.TemporaryDirectory() as d:
            code, err, out = cli_run(scene, d)
            self.assertEqual(code, 0, err)
            with h5py.File(out, "r") as f:
                expected = numeric_datasets(f)
        with subslip.run(scene) as result:
            self.assertTrue(result.completed)
            got = numeric_datasets(result.file)
        self.assertGreater(len(expected), 3, relative)
        self.assert_bitwise(expected, got, relative)
        return expected

    def test_main_job(self):
        self.check_scene("inputs/default.yaml")

    def test_contact_scene(self):
        self.check_scene("inputs/hold_and_reslide.yaml")

    def test_sweep(self):
        expected = self.check_scene("inputs/paper_fig12_peak_bottom.yaml")
        self.assertEqual(len([n for n in expected if n.endswith("/mu")]), 5)

    def test_a_dict_is_its_yaml_file(self):
        scene = scene_path("inputs/paper_fig12_peak_bottom.yaml")
        with open(scene) as f:
            as_dict = yaml.safe_load(f)
        with subslip.run(scene) as a, subslip.run(as_dict) as b:
            self.assert_bitwise(numeric_datasets(a.file), numeric_datasets(b.file), "dict")

    def test_a_dict_loads_by_dot_f_and_first_piola(self):
        # DAMASK's tension load case written as a dict: F_33 = 1 + dot_F_33 t at every row, and
        # the lateral P = J sigma F^-T of the stored F and Cauchy stress at zero.
        scene = {
            "scene": "crystal",
            "units": {"stress": "MPa", "time": "s"},
            "phase": {
                "families": ["fcc_111_110"],
                "elasticity": {"type": "cubic", "C11": 168400, "C12": 121400, "C44": 75400},
                "tau0": 20.0,
                "law": {
                    "friction": {"mu_s": 1.0, "mu_k": 1.5, "kappa": 2.0, "xi": 0.0},
                    "subloading": {"function": "cot", "u_tilde": 300},
                    "overstress": {"form": "exponential", "eta_v": 0.05, "n": 16, "r_hat": 1.8},
                },
            },
            "orientations": {"random": {"count": 8, "seed": 3}},
            "loading": [{
                "dot_F": [["x", 0, 0], [0, "x", 0], [0, 0, 1.0e-3]],
                "P": [[0, "x", "x"], ["x", 0, "x"], ["x", "x", "x"]],
                "strain": 0.02,
                "increments": 20,
            }],
        }
        with subslip.run(scene) as r:
            macro = r.file["cases/base/macro"]
            f, sigma, t = macro["F"][()], macro["stress"][()], macro["time"][()]
        self.assertEqual(len(t), 21)
        self.assertLess(np.abs(f[:, 2, 2] - (1.0 + 1.0e-3 * t)).max(), 1e-14)
        p = np.linalg.det(f)[:, None, None] * sigma @ np.linalg.inv(f).transpose(0, 2, 1)
        scale = max(np.abs(sigma).max(), 20.0)
        self.assertLess(np.abs(p[:, [0, 1], [0, 1]]).max(), 1e-10 * scale)
        self.assertGreater(sigma[-1, 2, 2], 2 * 20.0)

    def test_output_writes_the_file_and_refuses_to_replace_it(self):
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "contact.h5")
            with subslip.run(CONTACT_SCENE, output=out) as r:
                self.assertEqual(r.path, out)
                mu = r.case("base").series("mu")
            self.assertTrue(os.path.isfile(out))
            with self.assertRaises(subslip.SceneError) as caught:
                subslip.run(CONTACT_SCENE, output=out)
            self.assertIn("--force", str(caught.exception))
            with subslip.run(CONTACT_SCENE, output=out, force=True) as r:
                self.assertEqual(r.case("base").series("mu").tobytes(), mu.tobytes())

    def test_overrides_are_the_command_lines_set(self):
        overrides = {"law.friction.mu_s": 0.1, "loading[1].slide.direction": [1, 0.25],
                     "loading[2].hold.duration": "1 min"}
        edited = copy.deepcopy(CONTACT_SCENE)
        edited["law"]["friction"]["mu_s"] = 0.1
        edited["loading"][1]["slide"]["direction"] = [1, 0.25]
        edited["loading"][2]["hold"]["duration"] = 60
        with subslip.run(CONTACT_SCENE, overrides=overrides) as a, subslip.run(edited) as b:
            self.assert_bitwise(numeric_datasets(b.file), numeric_datasets(a.file), "overrides")
            self.assertEqual([text(v) for v in a.file.attrs["scene_set"]],
                             ["law.friction.mu_s=0.1", "loading[1].slide.direction=[1, 0.25]",
                              "loading[2].hold.duration=1 min"])
            self.assertNotIn("scene_set", b.file.attrs)
        with self.assertRaises(subslip.SceneError) as caught:
            subslip.run(CONTACT_SCENE, overrides={"law.friction.mu_ss": 0.1})
        self.assertTrue(str(caught.exception).startswith(
            "--set law.friction.mu_ss=0.1: law.friction.mu_ss: unknown key 'mu_ss'"),
            str(caught.exception))

    def test_a_case_is_found_by_its_name_with_units(self):
        scene = copy.deepcopy(CONTACT_SCENE)
        scene["sweep"] = {"loading[0].slide.speed": ["0.01 mm/s", "1 mm/min"]}
        with subslip.run(scene) as r:
            self.assertEqual(r.all_cases, ["speed=0.01 mm_s", "speed=1 mm_min"])
            self.assertEqual(r.shown_name("speed=1 mm_min"), "speed=1 mm/min")
            self.assertEqual(r.case("speed=1 mm/min").name, "speed=1 mm_min")
            self.assertEqual(r.case("speed=1 mm/min").series("mu").tobytes(),
                             r.case("speed=1 mm_min").series("mu").tobytes())

    def test_an_in_memory_result_leaves_no_file(self):
        def ours():
            return {n for n in os.listdir(tempfile.gettempdir()) if n.startswith("subslip-run-")}

        before = ours()
        with subslip.run(CONTACT_SCENE) as r:
            self.assertIsNotNone(r.image)
        self.assertEqual(ours() - before, set())


class Threads(unittest.TestCase):
    def run_in_threads(self, work, count=4):
        results, failures = [None] * count, []

        def one(k):
            try:
                results[k] = work()
            except Exception as e:  # reported below, not lost in the thread
                failures.append(e)

        threads = [threading.Thread(target=one, args=(k,)) for k in range(count)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        self.assertEqual(failures, [])
        return results

    def assert_releases_the_gil(self, work, repeats=100):
        """`work` lets another thread run while it computes: with a switch interval longer than
        any run, the main thread gets the interpreter back before the worker ends only if the
        core releases it. The worker repeats `work` until the main thread has run (or `repeats`
        times), so that a main thread the system schedules late on a loaded machine still finds
        a call in progress; between two calls the worker keeps the interpreter."""
        started, state = threading.Event(), {"done": False, "seen": False}

        def worker():
            started.set()  # (wakes the main thread, which then waits for the interpreter)
            for _ in range(repeats):
                work()
                if state["seen"]:
                    break
            state["done"] = True

        interval = sys.getswitchinterval()
        sys.setswitchinterval(1000.0)
        try:
            thread = threading.Thread(target=worker)
            thread.start()
            started.wait()
            ran_meanwhile = not state["done"]
            state["seen"] = True
            thread.join()
        finally:
            sys.setswitchinterval(interval)
        self.assertTrue(ran_meanwhile)

    def test_the_core_computes_without_the_gil(self):
        # The compiled calls themselves, their arguments made before: nothing else between the
        # worker's started.set() and its end could hand the interpreter over (file system
        # calls in subslip.run's own code would).
        core = subslip._native.core()
        scene = scene_path("inputs/paper_fig12_peak_bottom.yaml")
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "r.h5")
            self.assert_releases_the_gil(lambda: core.run_scene(scene, "", out, False, 0))
        point = core.TaylorPoint(*subslip.scene_source.scene_source(TAYLOR_SCENE), "")
        gradients, dt = point.steps()
        self.assert_releases_the_gil(lambda: point.along_path(gradients, dt, None))

    def test_four_runs_at_once_are_identical(self):
        scene = scene_path("inputs/paper_fig12_peak_bottom.yaml")

        def work():
            with subslip.run(scene) as r:
                return numeric_datasets(r.file)

        results = self.run_in_threads(work)
        for other in results[1:]:
            self.assertEqual(sorted(other), sorted(results[0]))
            for name, a in results[0].items():
                self.assertEqual(a.tobytes(), other[name].tobytes(), name)

    def test_four_taylor_points_at_once_are_identical(self):
        point = subslip.TaylorPoint(TAYLOR_SCENE)
        gradients, dt = point.steps()
        results = self.run_in_threads(lambda: point.along_path(gradients, dt)["stress"])
        for other in results[1:]:
            self.assertEqual(other.tobytes(), results[0].tobytes())


class BadScenes(unittest.TestCase):
    BAD = ["tests/data/scenes/unknown_key.yaml", "tests/data/scenes/range_speed.yaml",
           "tests/data/scenes/malformed.yaml", "tests/data/scenes/bad_unit.yaml",
           "tests/data/crystal_scenes/bad_family.yaml",
           "tests/data/crystal_scenes/bad_orientation_path.yaml", "tests/data/no_such_scene.yaml"]

    def test_the_message_is_the_command_lines(self):
        for relative in self.BAD:
            scene = scene_path(relative)
            with tempfile.TemporaryDirectory() as d:
                code, err, _ = cli_run(scene, d)
            self.assertEqual(code, 2, relative)
            prefix = "subslip: error: "
            self.assertTrue(err.startswith(prefix), err)
            with self.assertRaises(subslip.SceneError) as caught:
                subslip.run(scene)
            self.assertIsInstance(caught.exception, ValueError)
            self.assertEqual(str(caught.exception), err[len(prefix):].rstrip("\n"), relative)

    def test_a_bad_dict_names_its_line_and_key(self):
        scene = copy.deepcopy(CONTACT_SCENE)
        scene["law"]["friction"]["mu_s"] = -1.0
        with self.assertRaises(subslip.SceneError) as caught:
            subslip.run(scene)
        message = str(caught.exception)
        self.assertTrue(message.startswith("<scene dict>:"), message)
        self.assertIn("mu_s", message)
        for point in (subslip.ContactPoint,):
            with self.assertRaises(subslip.SceneError):
                point(scene)
        with self.assertRaises(subslip.SceneError):
            subslip.TaylorPoint(scene_path("tests/data/crystal_scenes/bad_family.yaml"))

    def test_warnings_become_python_warnings(self):
        scene = copy.deepcopy(CONTACT_SCENE)
        scene["contact"]["normal_traction"] = 5.56e9  # [MPa]: a plausibility warning
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            subslip.run(scene).close()
        self.assertTrue(any(issubclass(w.category, subslip.SceneWarning) for w in caught),
                        [str(w.message) for w in caught])

    def test_bad_arrays_are_refused_by_name(self):
        point = subslip.ContactPoint(CONTACT_SCENE)
        with self.assertRaisesRegex(ValueError, "slip increments"):
            point.along_path(np.zeros((3, 3)), 5.56, [1.0, 1.0, 1.0])
        with self.assertRaisesRegex(ValueError, "dt"):
            point.along_path(np.zeros((3, 2)), 5.56, 1.0)
        with self.assertRaisesRegex(ValueError, "dt must be positive"):  # the point's check
            point.along_path(np.zeros((1, 2)), 5.56, [0.0])

    def test_a_step_the_point_cannot_take_raises_step_failure(self):
        scene = copy.deepcopy(CONTACT_SCENE)
        scene["integrator"] = {"method": "forward_euler"}
        point = subslip.ContactPoint(scene)
        with self.assertRaisesRegex(subslip.StepFailure, "^step 1: "):  # a slide of 0.5 mm at once
            point.along_path([[0.0, 0.0], [0.5, 0.0]], 5.56, [1.0, 1.0])


class PointsEqualTheDrivers(unittest.TestCase):
    def test_contact_point_along_the_scenes_steps(self):
        point = subslip.ContactPoint(CONTACT_SCENE)
        du, fn, dt = point.steps()
        self.assertEqual(len(dt), 550)
        path = point.along_path(du, fn, dt)
        with subslip.run(CONTACT_SCENE) as r:
            case = r.case("base")
            traction = case.raw("traction")
            self.assertEqual(traction.shape, (len(dt) + 1, 3))
            rows = {
                "traction": (traction[1:, :2], path["traction"]),
                "normal_traction": (traction[1:, 2], path["normal_traction"]),
                "slip": (case.raw("slip")[1:], path["slip"]),
            }
            for name in ("mu", "r", "r_s", "vp_slip"):
                rows[name] = (case.raw(name)[1:], path[name])
        for name, (driver, api) in rows.items():
            self.assertEqual(driver.shape, api.shape, name)
            self.assertEqual(driver.tobytes(), api.tobytes(), name)

    def test_contact_point_continues_from_a_state(self):
        point = subslip.ContactPoint(CONTACT_SCENE)
        du, fn, dt = point.steps()
        whole = point.along_path(du, fn, dt)
        first = point.along_path(du[:300], fn[:300], dt[:300])
        rest = point.along_path(du[300:], fn[300:], dt[300:], state=first["state"])
        self.assertEqual(rest["traction"].tobytes(), whole["traction"][300:].tobytes())
        self.assertEqual(rest["mu"].tobytes(), whole["mu"][300:].tobytes())

    def test_taylor_and_grain_points_along_the_scenes_steps(self):
        taylor = subslip.TaylorPoint(TAYLOR_SCENE)
        self.assertEqual(taylor.grain_count, 5)
        gradients, dt = taylor.steps()
        self.assertEqual(gradients.shape, (61, 3, 3))
        self.assertEqual(dt.tobytes(), np.concatenate([
            subslip.increment_lengths(5.0, 25), subslip.increment_lengths(2.0, 20, 1.1),
            subslip.increment_lengths(4.0, 16)]).tobytes())
        path = taylor.along_path(gradients, dt)
        with subslip.run(TAYLOR_SCENE) as r:
            case = r.case("base")
            macro = case.series("macro/stress")
            grains = case.series("grains/stress")
            slip = case.grains("slip")
        self.assertEqual(macro.shape, (62, 3, 3))
        self.assertEqual(macro[1:].tobytes(), path["stress"].tobytes())
        self.assertEqual(path["tangent"].shape, (61, 6, 6))
        self.assertTrue(np.all(path["iterations"] >= 1))
        for g in (0, 3):
            grain = subslip.GrainPoint(TAYLOR_SCENE, grain=g).along_path(gradients, dt)
            self.assertEqual(grains[1:, g].tobytes(), grain["stress"].tobytes(), f"grain {g}")
            self.assertEqual(slip[-1, g].tobytes(), grain["state"]["slip"][0].tobytes())
        self.assertEqual(path["state"]["slip"][3].tobytes(), slip[-1, 3].tobytes())
        with self.assertRaises(IndexError):
            subslip.GrainPoint(TAYLOR_SCENE, grain=5)


class GrainSensitivities(unittest.TestCase):
    """GrainPoint.sensitivities_along_path: the path along_path takes, with its derivatives in
    the named columns (their accuracy for every column: tests/test_grain_sensitivity.cpp)."""

    def path(self, scene):
        grain = subslip.GrainPoint(scene, grain=1)
        gradients, dt = grain.steps()
        return grain, gradients[:30], dt[:30]

    def test_columns_are_the_named_constants(self):
        grain, gradients, dt = self.path(TAYLOR_SCENE)
        carried = grain.sensitivities_along_path(gradients, dt)
        self.assertEqual(carried["parameters"], ["mu_s", "mu_k", "kappa", "xi", "u_tilde",
                                                 "eta_v", "n", "r_hat", "tau0", "initial_mu"])
        plain = grain.along_path(gradients, dt)
        self.assertEqual(carried["stress"].tobytes(), plain["stress"].tobytes())
        self.assertEqual(carried["d_stress"].shape, (30, 3, 3, 10))
        self.assertEqual(carried["d_mu"].shape, (30, 12, 10))
        # kappa (a law constant) and tau0 (the phase's) against central differences of whole
        # runs, Richardson-extrapolated from relative steps 2e-4 and 1e-4.
        for column, key in ((2, ("law", "friction", "kappa")), (8, ("tau0",))):
            def stress_with(factor):
                scene = copy.deepcopy(TAYLOR_SCENE)
                block = scene["phase"]
                for k in key[:-1]:
                    block = block[k]
                block[key[-1]] *= factor
                return subslip.GrainPoint(scene, grain=1).along_path(gradients, dt)["stress"]

            value = TAYLOR_SCENE["phase"]
            for k in key:
                value = value[k]
            central = [(stress_with(1 + h) - stress_with(1 - h)) / (2 * h * value)
                       for h in (2e-4, 1e-4)]
            difference = (4 * central[1] - central[0]) / 3
            derivative = carried["d_stress"][..., column]
            scale = np.abs(derivative).max()
            self.assertGreater(scale, 0.0)
            self.assertLessEqual(np.abs(derivative - difference).max(), 1e-6 * scale, key)

    def test_a_pressure_sensitive_phase_is_refused(self):
        scene = copy.deepcopy(TAYLOR_SCENE)
        scene["phase"]["pressure_sensitive"] = True
        grain, gradients, dt = self.path(scene)
        with self.assertRaises(ValueError):
            grain.sensitivities_along_path(gradients, dt)


@unittest.skipUnless(shutil.which("pip3") or os.path.exists("/usr/bin/pip3"), "needs pip")
class Fit(unittest.TestCase):
    """subslip.fit is `subslip fit --json`: the same report, the same error messages."""
    EXAMPLE = scene_path("inputs", "contact_fit_five_speeds.yaml")

    def test_the_report_is_the_command_lines(self):
        done = subprocess.run([BINARY, "fit", self.EXAMPLE, "--json"], capture_output=True,
                              text=True, cwd=SOURCE)
        self.assertEqual(done.returncode, 0, done.stderr)
        with warnings.catch_warnings(record=True) as issued:
            warnings.simplefilter("always", subslip.FitWarning)
            report = subslip.fit(self.EXAMPLE)
        self.assertEqual(report, json.loads(done.stdout))
        self.assertEqual([str(w.message) for w in issued], report["warnings"])
        self.assertTrue(report["converged"])
        self.assertEqual(len(report["estimate"]), 8)
        with tempfile.TemporaryDirectory() as d:
            figure = os.path.join(d, "fit.png")
            subslip.fit_figure(report, figure)
            with open(figure, "rb") as f:
                self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
            self.assertEqual(os.listdir(d), ["fit.png"])

    def test_a_bad_curve_raises_the_command_lines_message(self):
        with tempfile.TemporaryDirectory() as d:
            with open(self.EXAMPLE, encoding="utf-8") as f:
                text = f.read()
            fit = os.path.join(d, "fit.yaml")
            with open(fit, "w", encoding="utf-8") as f:
                f.write(text)
            os.mkdir(os.path.join(d, "fit_curves"))
            for speed in (1, 10, 50, 100, 200):
                with open(os.path.join(d, "fit_curves", f"speed_{speed}.csv"), "w") as f:
                    f.write("slip [mm], ratio [-]\n0.1, 0.09\n0.2, nan\n")
            done = subprocess.run([BINARY, "fit", fit], capture_output=True, text=True)
            self.assertEqual(done.returncode, 2)
            with self.assertRaises(subslip.SceneError) as caught:
                subslip.fit(fit)
        prefix = "subslip: error: "
        self.assertTrue(done.stderr.startswith(prefix), done.stderr)
        self.assertEqual(str(caught.exception), done.stderr[len(prefix):].rstrip("\n"))
        self.assertIn("speed_1.csv:3: ratio: not a finite number", str(caught.exception))


class CrystalFit(unittest.TestCase):
    """A crystal fit file through subslip.fit is `subslip fit --json` on it; its bad inputs are
    the command line's messages, each naming the file, the line and the key or column."""
    EXAMPLE = scene_path("inputs", "crystal_fit_three_orientations.yaml")

    def _example_in_fewer_steps(self, directory):
        # The shipped example with its path in 60 steps instead of 300 (a third of the run time;
        # what is compared is the two reports, not the fit's accuracy), its curves by full path.
        curves = scene_path("inputs", "fit_curves") + os.sep
        with open(self.EXAMPLE, encoding="utf-8") as f:
            text = f.read()
        self.assertIn("steps: {increments: 300}", text)
        text = text.replace("steps: {increments: 300}", "steps: {increments: 60}")
        text = text.replace("file: fit_curves/", "file: " + curves)
        path = os.path.join(directory, "example.yaml")
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
        return path

    def test_the_report_is_the_command_lines(self):
        with tempfile.TemporaryDirectory() as d:
            example = self._example_in_fewer_steps(d)
            done = subprocess.run([BINARY, "fit", example, "--json"], capture_output=True,
                                  text=True, cwd=SOURCE)
            self.assertEqual(done.returncode, 0, done.stderr)
            with warnings.catch_warnings(record=True):
                warnings.simplefilter("always", subslip.FitWarning)
                report = subslip.fit(example)
        self.assertEqual(report, json.loads(done.stdout))
        self.assertEqual(report["kind"], "crystal")
        self.assertTrue(report["converged"])
        self.assertEqual(sorted(report["estimate"]), ["kappa", "mu_k", "mu_s", "u_tilde"])
        self.assertEqual(report["unit"]["kappa"], "1")
        self.assertEqual(report["stress_unit"], "MPa")
        # The CRSS the curves determine: mu_s tau0 (tau0 = 10 MPa in the file) at the estimate.
        self.assertEqual(report["initial_crss"]["unit"], "MPa")
        self.assertAlmostEqual(report["initial_crss"]["value"],
                               10.0 * report["estimate"]["mu_s"], places=9)
        self.assertEqual([c["orientation"] for c in report["curves"]],
                         [[90, 90, 0], [90, 35.2643897, 225], [90, 53.3007748, 153.4349488]])
        for c in report["curves"]:
            self.assertEqual(len(c["strain"]), 60)
            self.assertEqual(len(c["fit"]), 60)
        with tempfile.TemporaryDirectory() as d:
            figure = os.path.join(d, "fit.png")
            subslip.fit_figure(report, figure)
            with open(figure, "rb") as f:
                self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
            self.assertEqual(os.listdir(d), ["fit.png"])

    def test_the_model_is_the_fits(self):
        # A curve made by crystal_fit_predict from a scene's phase, fitted from mu_s 25 % off:
        # the fit finds the scene's mu_s, and its model there is the curve.
        scene = scene_path("inputs", "fcc_single_crystal_tension_001.yaml")
        strain = np.geomspace(0.002, 0.05, 12)
        stress = subslip._native.core().crystal_fit_predict(scene, "", "", [90, 35.2643897, 225],
                                                            1.0e-3, strain, 100)
        self.assertEqual(stress.shape, (12,))
        self.assertTrue(np.all(np.diff(stress) > 0.0))  # hardening in tension
        with tempfile.TemporaryDirectory() as d:
            with open(os.path.join(d, "a.csv"), "w", encoding="utf-8") as f:
                f.write("strain [-], stress [MPa]\n")
                for e, s in zip(strain, stress):
                    f.write(f"{e!r}, {s!r}\n")
            fit = self._file(d, "mu_s: [1, 3]", "steps: {increments: 100}\n", mu_s="2.0")
            report = subslip.fit(fit)
        self.assertTrue(report["converged"], report["termination"])
        self.assertAlmostEqual(report["estimate"]["mu_s"], 1.6, places=5)
        np.testing.assert_allclose(report["curves"][0]["fit"], stress, rtol=1e-6)

    def test_the_model_is_the_tension_scenes_run(self):
        # crystal_fit_predict's path (calibration::predict) against `subslip run` of the shipped
        # [001] tension scene, the same grain, loading and 200 steps: sigma11 at every step's
        # ln F11, to within the scene's mixed-control stress tolerance.
        scene = scene_path("inputs", "fcc_single_crystal_tension_001.yaml")
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "run.h5")
            done = subprocess.run([BINARY, "run", scene, "-o", out, "--quiet"],
                                  capture_output=True, text=True)
            self.assertEqual(done.returncode, 0, done.stderr)
            with h5py.File(out, "r") as f:
                F = f["cases/base/macro/F"][1:]
                sigma = f["cases/base/macro/stress"][1:, 0, 0]
        strain = np.log(F[:, 0, 0])
        model = subslip._native.core().crystal_fit_predict(scene, "", "", [90, 90, 0], 1.0e-3,
                                                           strain, 200)
        np.testing.assert_allclose(model, sigma, rtol=0, atol=1e-5 * np.max(np.abs(sigma)))

    @staticmethod
    def _file(d, free, extra="", rate="1.0e-3", mu_s="1.6"):
        path = os.path.join(d, "fit.yaml")
        with open(path, "w", encoding="utf-8") as f:
            f.write("fit: crystal\nunits: {stress: MPa, time: s}\nphase:\n"
                    "  families: [fcc_111_110]\n"
                    "  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}\n"
                    "  tau0: 10\n"
                    "  law:\n"
                    f"    friction: {{mu_s: {mu_s}, mu_k: 14.8, kappa: 20, xi: 0}}\n"
                    "    subloading: {function: cot, u_tilde: 200}\n"
                    "    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}\n"
                    f"free:\n  {free}\n"
                    "curves:\n"
                    "  - {file: a.csv, orientation: [90, 35.2643897, 225], "
                    f"strain_rate: {rate}}}\n" + extra)
        return path

    def test_bad_inputs_raise_the_command_lines_messages(self):
        good = "strain [-], stress [MPa]\n0.002, 20\n0.004, 25\n"
        cases = [  # (curve file, free, strain rate, file:line: key, a part of the message)
            ("strain [-], stress [MPa]\n0.002, 20\n0.004, nan\n", "mu_s: [1, 3]", "1.0e-3",
             "a.csv:3: stress", "not a finite number"),
            ("strain [-], stress [MPa]\n0.002, 20\n0.006, 25\n0.004, 27\n", "mu_s: [1, 3]",
             "1.0e-3", "a.csv:4: strain", "increase in magnitude"),
            ("strain [-], sigma [MPa]\n0.002, 20\n", "mu_s: [1, 3]", "1.0e-3",
             "a.csv:1: stress", "missing column"),
            ("strain [-], stress [s]\n0.002, 20\n", "mu_s: [1, 3]", "1.0e-3",
             "a.csv:1: stress", "not a stress"),
            (good, "mu_s: [1, 3]", "-1.0e-3", "a.csv:2: strain", "strain rate's sign"),
            (good, "mu_s: [2, 5]", "1.0e-3", "fit.yaml:12: free.mu_s",
             "exclude the start mu_s = 1.6"),
            (good, "tau0: [5, 20]", "1.0e-3", "fit.yaml:12: free.tau0", "tau0 cannot be fitted"),
        ]
        prefix = "subslip: error: "
        for csv, free, rate, where, part in cases:
            with self.subTest(where=where), tempfile.TemporaryDirectory() as d:
                with open(os.path.join(d, "a.csv"), "w", encoding="utf-8") as f:
                    f.write(csv)
                fit = self._file(d, free, rate=rate)
                done = subprocess.run([BINARY, "fit", fit], capture_output=True, text=True)
                self.assertEqual(done.returncode, 2, done.stderr)
                with self.assertRaises(subslip.SceneError) as caught:
                    subslip.fit(fit)
                message = str(caught.exception)
                self.assertEqual(message, done.stderr[len(prefix):].rstrip("\n"))
                self.assertIn(os.path.join(d, where) + ": ", message)
                self.assertIn(part, message)


class OfflineInstall(unittest.TestCase):
    def test_pip_installs_the_package_with_its_core(self):
        with tempfile.TemporaryDirectory() as d:
            source = os.path.join(d, "source")  # (pip builds in the tree it is given)
            shutil.copytree(os.path.join(SOURCE, "python"), source,
                            ignore=shutil.ignore_patterns("__pycache__", "tests"))
            target = os.path.join(d, "site")
            env = dict(os.environ, PIP_NO_CACHE_DIR="1", PIP_DISABLE_PIP_VERSION_CHECK="1")
            env.setdefault("SUBSLIP_CORE_DIR", os.path.join(SOURCE, "build", "python"))
            done = subprocess.run(
                ["/usr/bin/python3", "-m", "pip", "install", "--no-build-isolation", "--no-index",
                 "--target", target, source], capture_output=True, text=True, env=env)
            self.assertEqual(done.returncode, 0, done.stdout + done.stderr)
            check = ("import subslip, sys; r = subslip.run('" + scene_path("inputs",
                     "paper_fig12_peak_bottom.yaml") + "'); "
                     "print(sys.modules['subslip._core'].__file__, len(r.cases))")
            env = {k: v for k, v in os.environ.items() if k not in ("SUBSLIP_CORE_DIR",)}
            env["PYTHONPATH"] = target
            done = subprocess.run(["/usr/bin/python3", "-c", check], capture_output=True,
                                  text=True, env=env, cwd=d)
            self.assertEqual(done.returncode, 0, done.stderr)
            module, cases = done.stdout.split()
            self.assertTrue(module.startswith(os.path.join(target, "subslip")), module)
            self.assertEqual(cases, "5")


if __name__ == "__main__":
    unittest.main()
