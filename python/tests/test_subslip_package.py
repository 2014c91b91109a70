#!/usr/bin/python3
"""Tests of the Python package python/subslip (run by ctest; unittest, Debian's h5py/numpy).

    SUBSLIP_BINARY=build/src/subslip /usr/bin/python3 -m unittest discover -s python/tests -v

Without SUBSLIP_BINARY the subslip binary is taken from build/src/subslip when it exists; the
classes that run scenes are skipped when there is none. Geometry, tensor layouts, number
formatting, slip measures and dependency messages need no binary (synthetic data); the rest
runs the scenes of tests/data/post/ and checks the package against the file's raw datasets,
against what the program computed (summary attributes) and against the CSV files it exports.
"""

import csv
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(SOURCE, "python"))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree

import h5py  # noqa: E402
import numpy as np  # noqa: E402

import subslip  # noqa: E402
from subslip import csv_export, tensors, texture  # noqa: E402

POST_SCENES = os.path.join(SOURCE, "tests", "data", "post")
INT32_FILL = -2**31


def subslip_binary():
    given = os.environ.get("SUBSLIP_BINARY")
    if given:
        return given
    built = os.path.join(SOURCE, "build", "src", "subslip")
    return built if os.access(built, os.X_OK) else None


BINARY = subslip_binary()
needs_binary = unittest.skipUnless(BINARY, "no subslip binary: set SUBSLIP_BINARY")


def core_available():
    try:
        subslip._native.core()
        return True
    except subslip.MissingCore:
        return False


# The derived measures are computed by the compiled core (one implementation with `subslip
# post`); without it they cannot be tested here (ctest sets SUBSLIP_CORE_DIR).
needs_core = unittest.skipUnless(core_available(), "no compiled core: set SUBSLIP_CORE_DIR")


def run_scene(scene, out, *extra):
    subprocess.run([BINARY, "run", "-q", "-j", "1", "--force", "-o", out, scene, *extra],
                   check=True)
    return out


def points(x, y):
    """Projected points as a sorted array, for set comparisons."""
    p = np.round(np.stack([x, y], axis=1), 9) + 0.0  # + 0.0 turns -0 into 0
    return p[np.lexsort((p[:, 1], p[:, 0]))]


def equal_area(v):
    x, y, z = np.asarray(v, dtype=float) / np.linalg.norm(v)
    return x / math.sqrt(1 + z), y / math.sqrt(1 + z)


def inside(point, x, y):
    """Whether `point` is inside the closed polygon (x, y) (ray casting along +X)."""
    px, py = point
    crossings = 0
    for k in range(len(x)):
        x0, y0, x1, y1 = x[k - 1], y[k - 1], x[k], y[k]
        if (y0 > py) != (y1 > py) and px < x0 + (py - y0) * (x1 - x0) / (y1 - y0):
            crossings += 1
    return crossings % 2 == 1


def cubic_rotations():
    """The 24 proper rotations of the cube: signed permutation matrices of determinant 1."""
    out = []
    for perm in ([0, 1, 2], [1, 2, 0], [2, 0, 1], [0, 2, 1], [2, 1, 0], [1, 0, 2]):
        for signs in np.ndindex(2, 2, 2):
            m = np.zeros((3, 3))
            m[range(3), perm] = np.where(np.array(signs) == 1, -1.0, 1.0)
            if np.linalg.det(m) > 0:
                out.append(m)
    return out



def csv_tensor_values(path):
    """The last nine columns (a tensor's components 11 ... 33) of a CSV file's data rows."""
    with open(path, newline="") as f:
        table = list(csv.reader(f))
    return np.array([row[-9:] for row in table[1:]], dtype=float)

class Tensors(unittest.TestCase):
    @needs_core
    def test_von_mises_of_uniaxial_stress_is_its_axial_value(self):
        sigma = np.diag([0.0, 0.0, -123.4])
        self.assertAlmostEqual(subslip.von_mises_stress(sigma), 123.4, places=12)
        # A superposed pressure changes nothing; a stack of tensors gives one value each.
        stack = np.stack([sigma, sigma + 50.0 * np.eye(3)])
        np.testing.assert_allclose(subslip.von_mises_stress(stack), [123.4, 123.4], rtol=1e-14)

    @needs_core
    def test_von_mises_strain_of_isochoric_uniaxial_strain_is_its_axial_value(self):
        eps = np.diag([-0.01, -0.01, 0.02])
        self.assertAlmostEqual(subslip.von_mises_strain(eps), 0.02, places=15)
        # Pure shear eps_12 = g/2: von Mises g / sqrt(3).
        shear = np.array([[0.0, 0.05, 0.0], [0.05, 0.0, 0.0], [0.0, 0.0, 0.0]])
        self.assertAlmostEqual(subslip.von_mises_strain(shear), 0.1 / math.sqrt(3), places=15)

    def test_symmetric_layout_fills_both_shears(self):
        t = subslip.to_matrices([1.0, 2.0, 3.0, 4.0, 5.0, 6.0], "11 22 33 23 13 12")
        np.testing.assert_array_equal(t, [[1, 6, 5], [6, 2, 4], [5, 4, 3]])

    def test_format_3_tensors_are_taken_as_stored(self):
        t = np.arange(18.0).reshape(2, 3, 3)
        np.testing.assert_array_equal(subslip.to_matrices(t, tensors.TENSOR_CONVENTION), t)
        with self.assertRaises(subslip.LayoutError):  # the convention on 9 columns: not 3x3
            subslip.to_matrices(np.zeros((2, 9)), tensors.TENSOR_CONVENTION, "macro/stress")

    def test_layout_is_read_not_assumed(self):
        values = np.arange(9.0)
        row_major = "row-major 3x3: 11 12 13 21 22 23 31 32 33"
        np.testing.assert_array_equal(subslip.to_matrices(values, row_major),
                                      values.reshape(3, 3))
        column_order = "11 21 31 12 22 32 13 23 33"  # the same numbers stored column by column
        np.testing.assert_array_equal(subslip.to_matrices(values, column_order),
                                      values.reshape(3, 3).T)

    def test_unknown_layouts_fail_clearly(self):
        for layout in ("Mandel: 11 22 33 23 13 12",      # scaled shears: not plain components
                       "11 22 33 23 13",                  # five columns named for six values
                       "11 22 33 23 13 13",               # a component twice
                       "11 22 33 23 32 12"):              # 23 and 32 of a symmetric tensor
            with self.subTest(layout=layout):
                with self.assertRaises(subslip.LayoutError) as caught:
                    subslip.to_matrices(np.zeros(6), layout, "macro/stress")
                self.assertIn("macro/stress", str(caught.exception))

    def test_which_layouts_are_tensors(self):
        self.assertTrue(tensors.looks_like_tensor(tensors.TENSOR_CONVENTION))
        self.assertTrue(tensors.looks_like_tensor("row-major 3x3: 11 12 13 21 22 23 31 32 33"))
        self.assertTrue(tensors.looks_like_tensor("Mandel 11 22 33 23 13 12 with sqrt 2"))
        self.assertFalse(tensors.looks_like_tensor("w x y z"))
        self.assertFalse(tensors.looks_like_tensor(
            "one value per slip system, in the order of slip_systems"))


class Texture(unittest.TestCase):
    def test_cube_orientation_puts_100_at_centre_and_rim(self):
        x, y = subslip.pole_figure_points([[1.0, 0.0, 0.0, 0.0]], subslip.cubic_family((1, 0, 0)))
        expected = points(np.array([0.0, 1.0, -1.0, 0.0, 0.0]),
                          np.array([0.0, 0.0, 0.0, 1.0, -1.0]))
        np.testing.assert_allclose(points(x, y), expected, atol=1e-12)

    def test_a_turn_about_x_moves_001_towards_minus_y(self):
        # Passive 30 deg about x: crystal [001] along R_x(30) e_z = (0, -sin 30, cos 30).
        half = math.radians(15)
        x, y = subslip.pole_figure_points([[math.cos(half), math.sin(half), 0, 0]],
                                          [[0.0, 0.0, 1.0]])
        np.testing.assert_allclose([x[0], y[0]], equal_area((0, -0.5, math.sqrt(0.75))),
                                   atol=1e-12)

    def test_stereographic_projection(self):
        # 90 deg from the centre is the rim, 45 deg is at tan(22.5 deg).
        x, _ = texture.project([[1.0, 0.0, 0.0], [math.sqrt(0.5), 0.0, math.sqrt(0.5)]],
                               "stereographic")
        np.testing.assert_allclose(x, [1.0, math.tan(math.radians(22.5))], atol=1e-15)

    def test_inverse_pole_figure_corners(self):
        # Cube: sample z is crystal [001], the triangle's centre corner.
        x, y = subslip.inverse_pole_figure_points([[1.0, 0.0, 0.0, 0.0]])
        np.testing.assert_allclose([x[0], y[0]], [0.0, 0.0], atol=1e-15)
        # g with g e_z = [111]/sqrt3 (its third column): the [111] corner.
        g = np.linalg.qr(np.array([[1.0, 1.0, 0.0], [1.0, -1.0, 1.0], [1.0, 0.0, -1.0]]))[0]
        g = g[:, [1, 2, 0]] * np.sign(g[0, 0])  # third column along [111]
        g[:, 0] *= np.linalg.det(g)             # a proper rotation
        np.testing.assert_allclose(g[:, 2], np.full(3, 1 / math.sqrt(3)), atol=1e-15)
        x, y = subslip.inverse_pole_figure_points(texture.matrix_to_quaternion(g))
        np.testing.assert_allclose([x[0], y[0]], equal_area((1, 1, 1)), atol=1e-12)

    def test_inverse_pole_figure_ignores_cubic_symmetry(self):
        # Symmetrically equivalent orientations S g describe the same crystal: same point, and
        # every point lies in the standard triangle z >= x >= y >= 0.
        rng = np.random.default_rng(5)
        q = rng.normal(size=(50, 4))
        g = texture.quaternion_to_matrix(q)
        reference = subslip.inverse_pole_figure_points(q, (1.0, 2.0, 3.0))
        for s in cubic_rotations():
            moved = texture.matrix_to_quaternion(np.einsum("ij,gjk->gik", s, g))
            got = subslip.inverse_pole_figure_points(moved, (1.0, 2.0, 3.0))
            np.testing.assert_allclose(got, reference, atol=1e-12)
        v = texture.cubic_standard_triangle(texture.crystal_directions(q, (1.0, 2.0, 3.0)))
        self.assertTrue(np.all((v[:, 2] >= v[:, 0]) & (v[:, 0] >= v[:, 1]) & (v[:, 1] >= 0)))

    def test_triangle_outline_runs_through_the_corners(self):
        x, y = texture.standard_triangle_outline("cubic", points=5)
        corners = [equal_area(v) for v in ((0, 0, 1), (1, 0, 1), (1, 1, 1))]
        for k, corner in enumerate(corners):
            np.testing.assert_allclose([x[5 * k], y[5 * k]], corner, atol=1e-15)
        # A reduced direction falls inside the outline; [011] (y > x) is outside the triangle.
        reduced = equal_area(texture.cubic_standard_triangle([[3.0, 1.0, 7.0]])[0])
        self.assertTrue(inside(reduced, x, y))
        self.assertFalse(inside(equal_area((0.0, 1.0, 1.0)), x, y))

    def test_hexagonal_triangle(self):
        # a1 (x) and the {10-10} normal at 30 deg bound the sector; 50 deg folds onto 10 deg.
        v = texture.hexagonal_standard_triangle([[math.cos(math.radians(50)),
                                                  math.sin(math.radians(50)), -0.5]])
        self.assertAlmostEqual(math.degrees(math.atan2(v[0, 1], v[0, 0])), 10.0, places=12)
        self.assertAlmostEqual(v[0, 2], 0.5, places=15)

    def test_pole_density_is_one_on_average_and_peaks_at_the_poles(self):
        # Equal-area grid: the mean over the disk is the mean over the hemisphere, 1 MRD for any
        # texture (up to the grid's rim cells); a cube grain puts its {100} peak at the centre,
        # the kernel's own height there: 2 kappa / 6 (one of six poles, kappa >> 1).
        cube = [[1.0, 0.0, 0.0, 0.0]]
        turned = [[math.cos(0.3), math.sin(0.3) * 0.6, math.sin(0.3) * 0.8, 0.0]]
        for q in (cube, turned):
            X, Y, mrd = texture.pole_density(q, texture.cubic_family((1, 0, 0)),
                                             half_width_deg=15.0, resolution=301)
            self.assertAlmostEqual(np.nanmean(mrd), 1.0, delta=0.01)
        X, Y, mrd = texture.pole_density(cube, texture.cubic_family((1, 0, 0)),
                                         half_width_deg=10.0, resolution=101)
        kappa = texture.kernel_concentration(10.0)
        self.assertAlmostEqual(mrd[50, 50], 2.0 * kappa / 6.0, delta=1e-9 * kappa)
        self.assertEqual((X[50, 50], Y[50, 50]), (0.0, 0.0))
        self.assertTrue(np.isnan(mrd[0, 0]), "outside the disk")
        # Half the peak 10 deg from it (pole +-z: the pole's own kernel only, near the centre).
        X, Y, mrd = texture.pole_density(cube, [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]],
                                         half_width_deg=10.0, resolution=2001)
        row = mrd[1000, 1000:]
        half = np.flatnonzero(row <= 0.5 * row[0])[0]
        angle = math.degrees(math.acos(1.0 - X[1000, 1000 + half] ** 2))
        self.assertAlmostEqual(angle, 10.0, delta=0.1)
        # The grid's directions: the equal-area projection inverted.
        v = np.array([[0.6, 0.0, 0.8], [0.0, -1.0, 0.0], [0.36, 0.48, 0.8], [0.0, 0.0, 1.0]])
        X, Y = texture.project(v)
        np.testing.assert_allclose(texture.equal_area_inverse(X, Y), v, atol=1e-15)

    def test_pole_density_weights_grains(self):
        # A grain of weight 3 and one of weight 1: the density is their 3:1 mixture.
        a, b = [1.0, 0.0, 0.0, 0.0], [math.cos(0.4), math.sin(0.4), 0.0, 0.0]
        family = texture.cubic_family((1, 1, 1))
        _, _, both = texture.pole_density([a, b], family, weights=[3.0, 1.0], resolution=41)
        _, _, only_a = texture.pole_density([a], family, resolution=41)
        _, _, only_b = texture.pole_density([b], family, resolution=41)
        np.testing.assert_allclose(both, 0.75 * only_a + 0.25 * only_b, rtol=1e-12)

    def test_matrix_quaternion_round_trip(self):
        q = np.random.default_rng(2).normal(size=(200, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True) * np.sign(q[:, :1])
        np.testing.assert_allclose(texture.matrix_to_quaternion(texture.quaternion_to_matrix(q)),
                                   q, atol=1e-14)


class Numbers(unittest.TestCase):
    def test_forms_of_std_to_chars(self):
        cases = [(1e5, "1e+05"), (1e-4, "1e-04"), (20.0, "20"), (0.5, "0.5"), (-0.0, "-0"),
                 (0.0, "0"), (1.5e20, "1.5e+20"), (2.0**70, "1180591620717411303424"),
                 (0.1, "0.1"), (float("nan"), "nan"), (float("-inf"), "-inf"),
                 (123456.7, "123456.7")]
        for value, text in cases:
            with self.subTest(value=value):
                self.assertEqual(csv_export.exact_number(value), text)

    def test_every_number_reads_back_to_the_same_double(self):
        rng = np.random.default_rng(11)
        values = rng.normal(size=2000) * 10.0 ** rng.integers(-300, 300, size=2000)
        values = np.concatenate([values, [5e-324, 1.7976931348623157e308, 1 / 3]])
        back = np.array([float(csv_export.exact_number(v)) for v in values])
        np.testing.assert_array_equal(back.view(np.int64), values.view(np.int64))


def write_series(group, name, valid, reserved, **attrs):
    """A series as subslip lays it out: `reserved` rows, the first len(valid) written."""
    valid = np.asarray(valid, dtype=float)
    data = np.full((reserved,) + valid.shape[1:], np.nan)
    data[:len(valid)] = valid
    d = group.create_dataset(name, data=data, chunks=(2,) + valid.shape[1:],
                             maxshape=(None,) + valid.shape[1:])
    d.attrs.update(attrs)


@needs_core
class SlipMeasures(unittest.TestCase):
    """Two grains (weights 1/4, 3/4), two slip systems, three valid rows of five reserved."""

    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp(prefix="subslip_package_slip_")
        cls.addClassCleanup(shutil.rmtree, cls.dir, ignore_errors=True)
        cls.path = os.path.join(cls.dir, "slip.h5")
        with h5py.File(cls.path, "w") as f:
            f.attrs.update({"format": "subslip", "scene_kind": "crystal", "completed": 0})
            f.create_group("units").attrs.update({"stress": "MPa", "time": "s"})
            cases = f.create_group("cases")
            cases.attrs["names"] = ["base"]
            g = cases.create_group("base")
            g.attrs["slip_families"] = ["custom"]
            write_series(g, "macro/time", [0.0, 1.0, 2.0], 5, unit="s")
            grains = g.create_group("grains")
            grains["weight"] = np.array([0.25, 0.75])
            # system 0: s = x, m = y (shear 12); system 1: s = y, m = z (shear 23)
            grains["slip_systems"] = np.array([[1.0, 0, 0, 0, 1, 0], [0, 1.0, 0, 0, 0, 1]])
            grains["slip_systems"].attrs["labels"] = ["a", "b"]
            rates = [[[0, 0], [0, 0]], [[1, -2], [-3, 0]], [[0, 0], [0, 0]]]
            write_series(grains, "slip_rate", rates, 5, unit="1/s")
            # grain 0 slips forward 0.3 on system 0, then back 0.2; grain 1 does not slip
            slip = [[[0, 0], [0, 0]], [[0.3, 0], [0, 0]], [[0.1, 0], [0, 0]]]
            write_series(grains, "slip", slip, 5, unit="1")
            progress = f.create_group("progress")
            progress["rows"] = np.array([3])
            progress["state"] = np.array([1])

    def test_slip_activity_is_the_weighted_mean_of_abs_rates(self):
        with subslip.open(self.path) as r:
            activity = r.case("base").slip_activity()
        np.testing.assert_allclose(activity, [[0, 0], [0.25 * 1 + 0.75 * 3, 0.25 * 2], [0, 0]],
                                   rtol=1e-15)

    def test_equivalent_plastic_strain_accumulates_single_slip(self):
        # Slip g on one system is a shear strain g/2: von Mises equivalent g/sqrt3, and a
        # reversal adds (it is accumulated along the path, not the net slip).
        with subslip.open(self.path) as r:
            case = r.case("base")
            per_grain = case.equivalent_plastic_strain(per_grain=True)
            mean = case.equivalent_plastic_strain()
        root3 = math.sqrt(3.0)
        np.testing.assert_allclose(per_grain[:, 0], [0, 0.3 / root3, 0.5 / root3], rtol=1e-14)
        np.testing.assert_array_equal(per_grain[:, 1], [0, 0, 0])
        np.testing.assert_allclose(mean, 0.25 * per_grain[:, 0], rtol=1e-14)

    def test_slip_activity_per_grain_and_of_one_grain(self):
        with subslip.open(self.path) as r:
            case = r.case("base")
            every = case.slip_activity(per_grain=True)
            one = case.slip_activity(grain=1)
            with self.assertRaises(IndexError):
                case.slip_activity(grain=2)
        np.testing.assert_array_equal(every[1], [[1, 2], [3, 0]])
        self.assertEqual(every.shape, (3, 2, 2))
        np.testing.assert_array_equal(one, [[0, 0], [3, 0], [0, 0]])

    def test_equivalent_plastic_strain_of_one_grain(self):
        with subslip.open(self.path) as r:
            case = r.case("base")
            np.testing.assert_array_equal(case.equivalent_plastic_strain(grain=0),
                                          case.equivalent_plastic_strain(per_grain=True)[:, 0])
            self.assertEqual(case.equivalent_plastic_strain(grain=0).shape, (3,))

    def test_per_grain_rows_have_their_times(self):
        with subslip.open(self.path) as r:
            np.testing.assert_array_equal(r.case("base").grain_time(), [0.0, 1.0, 2.0])

    def test_missing_field_names_the_output_setting(self):
        with subslip.open(self.path) as r:
            with self.assertRaises(subslip.MissingData) as caught:
                r.case("base").grains("crss")
            self.assertIn("grains/crss", str(caught.exception))
            with self.assertRaises(subslip.MissingData) as caught:
                r.case("base").orientations()
            self.assertIn("output: {grains: [orientation]}", str(caught.exception))


class MissingDependencies(unittest.TestCase):
    """A module that cannot be imported gives one message naming the Debian package."""

    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="subslip_package_deps_")
        self.addCleanup(shutil.rmtree, self.dir, ignore_errors=True)

    def hide(self, module):
        """A PYTHONPATH under which `import module` fails as if it were not installed."""
        with open(os.path.join(self.dir, module + ".py"), "w") as f:
            f.write(f"raise ModuleNotFoundError(\"No module named '{module}'\")\n")
        return {**os.environ, "PYTHONPATH": self.dir + os.pathsep + os.path.join(SOURCE, "python"),
                "PYTHONDONTWRITEBYTECODE": "1"}

    def test_package_names_python3_h5py(self):
        run = subprocess.run([sys.executable, "-c", "import subslip"], env=self.hide("h5py"),
                             capture_output=True, text=True)
        self.assertNotEqual(run.returncode, 0)
        self.assertIn("apt-get install python3-h5py", run.stderr)
        self.assertIn("MissingDependency", run.stderr)

    def test_plot_script_names_python3_matplotlib_without_traceback(self):
        script = os.path.join(SOURCE, "scripts", "subslip_plots.py")
        for module in ("matplotlib", "numpy"):
            with self.subTest(module=module):
                run = subprocess.run([sys.executable, script, "x.h5"], env=self.hide(module),
                                     capture_output=True, text=True)
                self.assertEqual(run.returncode, 2, run.stderr)
                self.assertIn(f"apt-get install python3-{module}", run.stderr)
                self.assertNotIn("Traceback", run.stderr)


@needs_binary
class Runs(unittest.TestCase):
    """The scenes of tests/data/post/ run by subslip, read with the package."""

    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp(prefix="subslip_package_")
        cls.addClassCleanup(shutil.rmtree, cls.dir, ignore_errors=True)
        cls.files = {}
        for scene in ("crystal_small", "contact_small", "single_crystal_euler",
                      "crystal_adaptive", "crystal_grains_at"):
            cls.files[scene] = run_scene(os.path.join(POST_SCENES, scene + ".yaml"),
                                         os.path.join(cls.dir, scene + ".h5"))

    def copy(self, scene, name):
        path = os.path.join(self.dir, name)
        shutil.copyfile(self.files[scene], path)
        return path

    # ---- valid rows

    def test_finished_adaptive_run_has_no_padding_rows(self):
        with subslip.open(self.files["crystal_adaptive"]) as r:
            self.assertTrue(r.completed)
            case = r.case("base")
            rows = case.valid_rows
            # The run reserved more rows than the adaptive steps took (the scene plans 200);
            # the finished file holds only the rows taken, as stored.
            self.assertTrue(r.finished)
            self.assertLess(rows, 201)
            for path in case.datasets():
                if case.is_series(path):
                    stored = case.dataset(path)
                    self.assertEqual(stored.shape[0], rows, path)
                    values = case.series(path)
                    self.assertEqual(len(values), rows, path)
                    self.assertTrue(np.isfinite(values).all(), path)
            self.assertNotIn(INT32_FILL, case.series("macro/segment"))
            self.assertEqual(case.time()[-1], case.attrs["final_time"])

    def test_rows_at_strains_and_grain_rows_at_the_coarser_points(self):
        with subslip.open(self.files["crystal_grains_at"]) as r:
            case = r.case("base")
            # Macro rows: the initial state and every 0.1 % of loading strain (1e-3 /s).
            np.testing.assert_allclose(case.time(), np.arange(21) * 1.0, rtol=1e-13)
            np.testing.assert_allclose(case.series("macro/strain")[:, 2, 2],
                                       np.arange(21) * 1e-3, rtol=2e-6, atol=1e-18)
            # Per-grain rows at 0.5 %, 1 %, 2 %, each the state of its output row.
            np.testing.assert_array_equal(case.grain_rows(), [0, 5, 10, 20])
            self.assertEqual(case.valid_grain_rows, 4)
            self.assertEqual(case.grains("stress").shape, (4, 8, 3, 3))
            weights = case.grain_weights()
            mean = np.einsum("g,ngij->nij", weights, case.grains("stress"))
            np.testing.assert_allclose(mean, case.series("macro/stress")[case.grain_rows()],
                                       rtol=1e-12, atol=1e-9)
            # Killed before its end, a working file counts its per-grain rows apart.
            path = self.copy("crystal_grains_at", "grains_at_cut.h5")
        with h5py.File(path, "r+") as f:
            f.attrs["finished"] = 0
            f["progress/rows"][0] = 12
            f["progress/grain_rows"][0] = 3
            f["progress/state"][0] = 1
        with subslip.open(path) as r:
            case = r.case("base")
            self.assertEqual(len(case.time()), 12)
            np.testing.assert_array_equal(case.grain_rows(), [0, 5, 10])
            self.assertEqual(len(case.grains("slip")), 3)

    def test_truncated_progress_gives_only_its_rows(self):
        # A run killed in its first case after 5 rows, after a restart: the rows beyond are
        # finite left-overs, so only /progress can tell them from valid ones.
        path = self.copy("crystal_small", "truncated.h5")
        with h5py.File(path, "r+") as f:
            f["progress/rows"][:] = [5, 0]
            f["progress/grain_rows"][:] = [5, 0]  # (format 3 counts per-grain rows apart)
            f["progress/state"][:] = [1, 0]
            f.attrs["completed"] = 0
            f.attrs["finished"] = 0
        full = subslip.open(self.files["crystal_small"])
        self.addCleanup(full.close)
        first, second = full.cases
        with subslip.open(path) as r:
            self.assertFalse(r.completed)
            self.assertEqual(r.cases, [first])
            self.assertEqual(r.all_cases, [first, second])
            self.assertEqual((r.state(first), r.state(second)), ("running", "not_started"))
            case = r.case(first)
            np.testing.assert_array_equal(case.series("macro/stress"),
                                          full.case(first).series("macro/stress")[:5])
            self.assertEqual(case.grains("slip").shape, (5, 20, 12))
            self.assertEqual(len(r.case(second).series("macro/time")), 0)
            # The CSV export cuts the same rows.
            [written] = case.to_csv(os.path.join(self.dir, "truncated"), ["macro/stress"])
            np.testing.assert_array_equal(csv_tensor_values(written).view(np.int64),
                                          case.raw("macro/stress").reshape(-1, 9).view(np.int64))

    # ---- tensors

    def test_every_tensor_is_stored_as_3x3_with_its_convention(self):
        with h5py.File(self.files["crystal_small"], "r") as f, \
                subslip.open(self.files["crystal_small"]) as r:
            name = r.cases[1]
            case = r.case(name)
            raw = f["cases"][name]
            self.assertEqual(int(f.attrs["format_version"]), 3)
            for path in ("macro/L", "macro/F", "macro/strain", "macro/stress", "grains/stress"):
                d = raw[path]
                self.assertEqual(d.shape[-2:], (3, 3), path)
                self.assertEqual(d.attrs["components"], tensors.TENSOR_CONVENTION, path)
                self.assertNotIn("layout", d.attrs, path)
                np.testing.assert_array_equal(case.series(path), d[()])
            # L is not symmetric under mixed control: [n, i, j] is L_ij (row i), as the
            # prescribed L_33 = 1e-3 shows; the grain stress is symmetric, stored in full.
            L = raw["macro/L"][()]
            rate = case.attrs["sweep:loading[0].L[2][2]"]
            np.testing.assert_array_equal(L[1:, 2, 2], np.full(len(L) - 1, rate))
            self.assertEqual(case.attrs["sweep:loading[0].L[2][2].unit"], "1/s")
            sigma = raw["grains/stress"][()]
            np.testing.assert_array_equal(sigma, np.swapaxes(sigma, -1, -2))
            self.assertGreater(np.abs(sigma[..., 0, 1]).max(), 0.0)
            np.testing.assert_array_equal(case.grains("stress", grain=3), sigma[:, 3])

    def test_format_2_tensor_columns_read_as_the_same_matrices(self):
        # An older file stored macro tensors as 9 row-major columns (attribute `layout`) and
        # per-grain stresses as 6 columns 11 22 33 23 13 12: rewritten so, they read the same.
        path = self.copy("crystal_small", "format2.h5")
        with subslip.open(self.files["crystal_small"]) as r:
            name = r.cases[0]
            expected = {p: r.case(name).series(p) for p in ("macro/stress", "grains/stress")}
        with h5py.File(path, "r+") as f:
            f.attrs["format_version"] = 2
            g = f["cases"][name]
            stress = g["macro/stress"][()]
            del g["macro/stress"]
            d = g.create_dataset("macro/stress", data=stress.reshape(len(stress), 9))
            d.attrs["layout"] = "row-major 3x3: 11 12 13 21 22 23 31 32 33"
            sigma = g["grains/stress"][()]
            del g["grains/stress"]
            voigt = np.stack([sigma[..., i, j] for i, j in
                              [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]], axis=-1)
            d = g.create_dataset("grains/stress", data=voigt, chunks=(1,) + voigt.shape[1:])
            d.attrs["components"] = "11 22 33 23 13 12"
        with subslip.open(path) as r:
            self.assertEqual(r.format_version, 2)
            for p, values in expected.items():
                np.testing.assert_array_equal(r.case(name).series(p), values, p)

    def test_unknown_layout_in_a_file_stops_with_the_dataset_name(self):
        path = self.copy("crystal_small", "mandel.h5")
        with h5py.File(path, "r+") as f:
            name = f["cases"].attrs["names"][0]
            f["cases"][name]["grains/stress"].attrs["components"] = "Mandel: 11 22 33 23 13 12 " \
                "with sqrt 2"
        with subslip.open(path) as r:
            case = r.case(r.cases[0])
            with self.assertRaises(subslip.LayoutError) as caught:
                case.grains("stress")
            self.assertIn("grains/stress", str(caught.exception))
            self.assertEqual(case.raw("grains/stress").shape, (21, 20, 3, 3))  # still readable

    @needs_core
    def test_von_mises_matches_the_programs_summary(self):
        with subslip.open(self.files["crystal_small"]) as r:
            for name in r.cases:
                case = r.case(name)
                # One implementation (crystal/measures.hpp): the summary's value exactly.
                self.assertEqual(case.von_mises_stress()[-1],
                                 case.attrs["final_von_mises_stress"])
                self.assertEqual(case.von_mises_strain()[-1],
                                 case.attrs["final_von_mises_strain"])
                self.assertEqual(case.loading_component(), (2, 2))

    @needs_core
    def test_per_grain_measures_are_the_tables_of_subslip_post(self):
        # Case methods and `subslip post --quantity` compute with the same code: equal bits.
        quantities = ["grains/von_mises_stress", "grains/equivalent_plastic_strain",
                      "grains/slip_activity"]
        with subslip.open(self.files["crystal_small"]) as r:
            case = r.case(r.cases[0])
            path = case.to_table(os.path.join(self.dir, "table"), quantities, grain=3)
            with open(path, newline="") as f:
                table = list(csv.reader(f))
            self.assertEqual(table[0][:4], ["step", "time [s]", "von_mises_stress [MPa]",
                                            "equivalent_plastic_strain [1]"])
            values = np.array(table[1:], dtype=float)
            np.testing.assert_array_equal(values[:, 1], case.grain_time())
            np.testing.assert_array_equal(values[:, 2], case.von_mises_stress(grain=3))
            np.testing.assert_array_equal(values[:, 3], case.equivalent_plastic_strain(grain=3))
            np.testing.assert_array_equal(values[:, 4:], case.slip_activity(grain=3))
            self.assertEqual(case.von_mises_stress(per_grain=True).shape, (21, 20))
            # A grain's von Mises stress is that of its own stress tensor.
            sigma = case.grains("stress", 3)[-1]
            deviator = sigma - np.trace(sigma) / 3.0 * np.eye(3)
            self.assertAlmostEqual(case.von_mises_stress(grain=3)[-1],
                                   math.sqrt(1.5 * np.sum(deviator * deviator)), delta=1e-10)

    def test_table_errors_are_the_programs(self):
        with subslip.open(self.files["crystal_small"]) as r:
            case = r.case(r.cases[0])
            with self.assertRaises(KeyError) as caught:
                case.to_table(os.path.join(self.dir, "bad"), ["macro/stres"])
        self.assertIn("no quantity 'macro/stres'", str(caught.exception))

    @needs_core
    def test_equivalent_plastic_strain_is_the_plastic_part_of_the_strain(self):
        # Tension to 2 %: the elastic strain is stress / E, 55 MPa / 67..191 GPa (copper) below
        # 4 % of the total, so the plastic strain of every grain is 96-100 % of it; it never
        # decreases.
        with subslip.open(self.files["crystal_small"]) as r:
            for name in r.cases:
                case = r.case(name)
                total = case.von_mises_strain()[-1]
                eps = case.equivalent_plastic_strain(per_grain=True)
                self.assertTrue(np.all(np.diff(eps, axis=0) >= 0.0))
                self.assertTrue(np.all(eps[-1] > 0.96 * total), eps[-1] / total)
                self.assertTrue(np.all(eps[-1] < total), eps[-1] / total)

    # ---- texture

    def test_inverse_pole_figure_of_the_euler_grain(self):
        # Bunge (90, 30, 0): g e_z = (sin 30 sin 0, sin 30 cos 0, cos 30) = (0, 1/2, cos 30),
        # which the cubic symmetry moves to (1/2, 0, cos 30) in the standard triangle.
        with subslip.open(self.files["single_crystal_euler"]) as r:
            case = r.case("base")
            self.assertEqual(case.lattice(), "cubic")
            x, y = case.inverse_pole_figure(step=0)
        np.testing.assert_allclose([x[0], y[0]], equal_area((0.5, 0.0, math.sqrt(0.75))),
                                   atol=1e-9)

    # ---- sweeps

    def test_sweep_labels_carry_units(self):
        with subslip.open(self.files["crystal_small"]) as r:
            self.assertEqual([r.case(n).label() for n in r.cases],
                             ["L[2][2]=0.001 1/s", "L[2][2]=0.1 1/s"])
        with subslip.open(self.files["contact_small"]) as r:
            self.assertEqual([r.case(n).label() for n in r.cases],
                             ["speed=1 mm/min", "speed=200 mm/min"])
        with subslip.open(self.files["single_crystal_euler"]) as r:
            self.assertEqual(r.case("base").label(), "base")

    # ---- CSV

    # `Case.to_csv` runs `subslip post --csv` (one writer): these check what it writes against
    # the file's own numbers, bit for bit.

    def test_csv_has_every_valid_row_of_every_case(self):
        for scene in ("crystal_small", "contact_small", "crystal_adaptive", "crystal_grains_at"):
            with subslip.open(self.files[scene]) as r:
                for name in r.cases:
                    with self.subTest(scene=scene, case=name):
                        case = r.case(name)
                        time = "time" if scene == "contact_small" else "macro/time"
                        written = case.to_csv(os.path.join(self.dir, scene + "_csv", name),
                                              [time])
                        self.assertEqual(len(written), 1)
                        with open(written[0], newline="") as f:
                            table = list(csv.reader(f))
                        times = np.array([row[-1] for row in table[1:]], dtype=float)
                        np.testing.assert_array_equal(times.view(np.int64),
                                                      case.time().view(np.int64))

    def test_csv_of_one_grain_is_that_grains_rows(self):
        with subslip.open(self.files["crystal_small"]) as r:
            case = r.case(r.cases[0])
            [written] = case.to_csv(os.path.join(self.dir, "one_grain"), ["grains/stress"],
                                    grain=4)
            np.testing.assert_array_equal(
                csv_tensor_values(written).view(np.int64),
                case.raw("grains/stress")[:, 4].reshape(-1, 9).view(np.int64))

    def test_csv_of_special_doubles_reads_back_to_the_same_doubles(self):
        values = [1e5, 1e-4, 5e-324, 1.7976931348623157e308, -0.0, float("nan"), float("inf"),
                  1 / 3, 2.0**53, 1e15, 1e16, 1.5e20, 123456789012345683968.0, 1e22, 1e23]
        values += list(np.random.default_rng(4).normal(size=200) * 10.0 ** np.arange(-100, 100))
        path = os.path.join(self.dir, "special.h5")
        with h5py.File(path, "w") as f:
            f.attrs["format"] = "subslip"
            f.create_group("cases").attrs["names"] = ["base"]
            f["cases"].create_group("base").create_dataset(
                "value", data=np.array(values), chunks=(8,), maxshape=(None,))
        with subslip.open(path) as r:
            [written] = r.case("base").to_csv(os.path.join(self.dir, "special"))
        with open(written, newline="") as f:
            read = np.array([row[-1] for row in list(csv.reader(f))[1:]], dtype=float)
        expected = np.array(values)
        self.assertEqual(np.isnan(read).tolist(), np.isnan(expected).tolist())
        finite = ~np.isnan(expected)
        np.testing.assert_array_equal(read[finite].view(np.int64), expected[finite].view(np.int64))

    def test_csv_reads_back_to_the_same_doubles(self):
        with subslip.open(self.files["crystal_small"]) as r:
            case = r.case(r.cases[1])
            written = case.to_csv(os.path.join(self.dir, "round_trip"),
                                  ["macro/stress", "grains/stress"])
            for path, target in zip(["macro/stress", "grains/stress"], written):
                with open(target, newline="") as f:
                    table = list(csv.reader(f))
                header, body = table[0], np.array(table[1:], dtype=float)
                values = body[:, -9:]  # a tensor: its nine components 11 ... 33
                self.assertEqual(header[-9:], [f"stress_{ij} [MPa]" for ij in
                                               ("11", "12", "13", "21", "22", "23", "31", "32",
                                                "33")])
                np.testing.assert_array_equal(values.ravel().view(np.int64),
                                              case.raw(path).ravel().view(np.int64))
                self.assertEqual(header[:2], ["step", "time [s]"])
            with self.assertRaises(FileExistsError):  # as subslip post without --force
                case.to_csv(os.path.join(self.dir, "round_trip"), ["macro/stress"])


@needs_binary
class KilledRun(unittest.TestCase):
    """A real run killed (SIGKILL) in its first case: only the rows it wrote are returned, the
    second case (never started) is not listed."""

    SCENE = """\
scene: crystal
title: "killed in its first case"
units: {stress: MPa, time: s}
phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}
  tau0: 10.0
  law:
    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20.0, xi: 0.0}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}
orientations:
  random: {count: 50, seed: 3}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    strain: 0.2
    increments: 10000
output:
  macro: [time, strain, stress, segment]
  checkpoint_every: 100
sweep:
  "loading[0].L[2][2]": [1.0e-3, 1.0e-2]
"""

    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="subslip_package_killed_")
        self.addCleanup(shutil.rmtree, self.dir, ignore_errors=True)
        self.scene = os.path.join(self.dir, "killed.yaml")
        with open(self.scene, "w") as f:
            f.write(self.SCENE)

    def run_and_kill(self, seconds):
        """Runs the scene and kills it `seconds` after its file appears (the program renames
        it into place once the layout is written)."""
        out = os.path.join(self.dir, "killed.h5")
        if os.path.exists(out):
            os.remove(out)
        child = subprocess.Popen([BINARY, "run", "-q", "-j", "1", "-o", out, self.scene])
        try:
            deadline = time.monotonic() + 60
            while not os.path.exists(out) and child.poll() is None:
                self.assertLess(time.monotonic(), deadline, "no result file after 60 s")
                time.sleep(0.02)
            time.sleep(seconds)
        finally:
            child.send_signal(signal.SIGKILL)
            code = child.wait()
        self.assertEqual(code, -signal.SIGKILL, "the run ended before it was killed")
        return out

    def test_only_valid_rows_of_a_killed_run(self):
        for seconds in (1.0, 4.0):  # a busy machine may not have written a row after 1 s
            path = self.run_and_kill(seconds)
            with h5py.File(path, "r") as f:
                rows = int(f["progress/rows"][0])
            if rows > 0:
                break
        self.assertGreater(rows, 0)
        with subslip.open(path) as r:
            self.assertFalse(r.completed)
            first, second = r.all_cases
            self.assertEqual(r.cases, [first])
            self.assertEqual(r.state(second), "not_started")
            case = r.case(first)
            self.assertEqual(case.valid_rows, rows)
            self.assertLess(rows, case.dataset("macro/time").shape[0])  # reserved rows follow
            for path in ("macro/time", "macro/strain", "macro/stress", "macro/segment"):
                values = case.series(path)
                self.assertEqual(len(values), rows, path)
                self.assertTrue(np.isfinite(values).all(), path)
            self.assertNotIn(INT32_FILL, case.series("macro/segment"))
            self.assertTrue(np.all(np.diff(case.time()) > 0))


if __name__ == "__main__":
    unittest.main()
