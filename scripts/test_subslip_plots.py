#!/usr/bin/python3
"""Tests of scripts/subslip_plots.py (run by ctest; unittest, Debian's h5py/numpy/matplotlib).

    /usr/bin/python3 scripts/test_subslip_plots.py PoleGeometry PanelChoice ReservedRows
    SUBSLIP_BINARY=build/src/subslip /usr/bin/python3 scripts/test_subslip_plots.py Pictures

PoleGeometry checks the projection and the rotation convention against hand-derived poles;
PanelChoice checks, on series written out here, how holds and a peak at the start are found;
Pictures runs subslip on the small scenes of tests/data/post/, draws them, checks the PNG files
(and --format pdf / svg, --dpi, legends with units, a time panel exactly for the scenes with
holds, a logarithmic strain panel exactly for the one with a peak at the start), and checks the
poles of a grain whose quaternion subslip wrote against g built by hand from its Euler angles
with the formula of include/subslip/crystal/rotation.hpp.
"""

import math
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import unittest

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.dirname(HERE)
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True  # no scripts/__pycache__ in the source tree
import subslip_plots as sp  # noqa: E402

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def points(x, y):
    """Projected points as a sorted array, for set comparisons."""
    p = np.round(np.stack([x, y], axis=1), 9) + 0.0  # + 0.0 turns -0 into 0
    return p[np.lexsort((p[:, 1], p[:, 0]))]


def project(v):
    """Equal-area projection written out for one upper-hemisphere unit vector."""
    x, y, z = v
    return x / math.sqrt(1 + z), y / math.sqrt(1 + z)


def bunge_matrix(phi1, Phi, phi2):
    """g of Bunge Euler angles (degrees), the formula in include/subslip/crystal/rotation.hpp."""
    c1, s1 = math.cos(math.radians(phi1)), math.sin(math.radians(phi1))
    c2, s2 = math.cos(math.radians(phi2)), math.sin(math.radians(phi2))
    c, s = math.cos(math.radians(Phi)), math.sin(math.radians(Phi))
    return np.array([[c1 * c2 - s1 * s2 * c, s1 * c2 + c1 * s2 * c, s2 * s],
                     [-c1 * s2 - s1 * c2 * c, -s1 * s2 + c1 * c2 * c, c2 * s],
                     [s1 * s, -c1 * s, c]])


class PoleGeometry(unittest.TestCase):
    def test_cube_orientation_puts_100_at_centre_and_rim(self):
        x, y = sp.pole_figure_points([[1.0, 0.0, 0.0, 0.0]], sp.cubic_family((1, 0, 0)))
        expected = points(np.array([0.0, 1.0, -1.0, 0.0, 0.0]),
                          np.array([0.0, 0.0, 0.0, 1.0, -1.0]))
        np.testing.assert_allclose(points(x, y), expected, atol=1e-12)

    def test_cube_orientation_111_and_110(self):
        # {111}: four poles at polar angle acos(1/sqrt3) = 54.74 deg, on the diagonals.
        x, y = sp.pole_figure_points([[1.0, 0.0, 0.0, 0.0]], sp.cubic_family((1, 1, 1)))
        r = math.sqrt(1 - 1 / math.sqrt(3))
        d = r / math.sqrt(2)
        expected = points(np.array([d, d, -d, -d]), np.array([d, -d, d, -d]))
        np.testing.assert_allclose(points(x, y), expected, atol=1e-12)
        # {110}: four on the rim at 45 deg, four at polar angle 45 deg on the axes.
        x, y = sp.pole_figure_points([[1.0, 0.0, 0.0, 0.0]], sp.cubic_family((1, 1, 0)))
        self.assertEqual(len(x), 8)
        radii = np.sort(np.hypot(x, y))
        np.testing.assert_allclose(radii[:4], math.sqrt(1 - 1 / math.sqrt(2)), atol=1e-12)
        np.testing.assert_allclose(radii[4:], 1.0, atol=1e-12)

    def test_rotation_is_not_transposed(self):
        # Passive 30 deg about sample x: the crystal frame is the sample frame turned by +30 deg
        # about x, so crystal [001] lies along R_x(30) e_z = (0, -sin 30, cos 30): below the
        # centre. With g instead of g^T it would land above it, at (0, +sin 30, cos 30).
        half = math.radians(15)
        q = [[math.cos(half), math.sin(half), 0.0, 0.0]]
        x, y = sp.pole_figure_points(q, np.array([[0.0, 0.0, 1.0]]))
        ex, ey = project((0.0, -0.5, math.cos(math.radians(30))))
        np.testing.assert_allclose([x[0], y[0]], [ex, ey], atol=1e-12)
        self.assertLess(y[0], -0.2)

    def test_quaternion_matrix_matches_rotation_hpp(self):
        # rotation.hpp: Euler (90, 0, 0) deg gives g = [[0,1,0],[-1,0,0],[0,0,1]], which is the
        # quaternion of 90 deg about z, (cos 45, 0, 0, sin 45).
        c = math.cos(math.radians(45))
        g = sp.quaternion_to_matrix([c, 0.0, 0.0, c])
        np.testing.assert_allclose(g, [[0, 1, 0], [-1, 0, 0], [0, 0, 1]], atol=1e-15)
        np.testing.assert_allclose(g, bunge_matrix(90, 0, 0), atol=1e-15)

    def test_projection_is_equal_area(self):
        # Uniform directions on the upper hemisphere: the fraction inside radius R must be R^2
        # (cap area 2 pi (1 - cos theta) over 2 pi, and R^2 = 1 - cos theta).
        rng = np.random.default_rng(3)
        v = rng.normal(size=(400000, 3))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        v[:, 2] = np.abs(v[:, 2])
        x, y = sp.upper_hemisphere_projection(v)
        r = np.hypot(x, y)
        self.assertLessEqual(r.max(), 1.0 + 1e-12)
        for R in (0.3, 0.5, 0.8):
            self.assertAlmostEqual(np.mean(r < R), R * R, delta=0.003)

    def test_hexagonal_poles(self):
        # c axis at the centre for the identity; six {10-10} normals on the rim at 30 + 60 k deg.
        x, y = sp.pole_figure_points([[1.0, 0.0, 0.0, 0.0]], sp.hexagonal_family("0001"))
        np.testing.assert_allclose(points(x, y), [[0.0, 0.0]], atol=1e-12)
        x, y = sp.pole_figure_points([[1.0, 0.0, 0.0, 0.0]], sp.hexagonal_family("10-10"))
        np.testing.assert_allclose(np.degrees(np.arctan2(y, x)) % 60.0, 30.0, atol=1e-9)


class PanelChoice(unittest.TestCase):
    """When a picture gets a time panel (holds) and a logarithmic panel (a peak at the start)."""

    def test_hold_intervals(self):
        # Slide 0 -> 1, hold 1 s, slide 1 -> 2, hold 2 s (two rows: merged into one interval).
        t = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
        x = np.array([0.0, 1.0, 1.0, 2.0, 2.0, 2.0])
        self.assertEqual(sp.hold_intervals(t, x), [(1.0, 2.0), (3.0, 5.0)])
        # Round-off far below the scale of x is no motion; a tiny real motion is.
        self.assertEqual(sp.hold_intervals([0.0, 1.0], [1.0, 1.0 + 1e-15]), [(0.0, 1.0)])
        self.assertEqual(sp.hold_intervals([0.0, 1.0], [1.0, 1.0 + 1e-9]), [])
        # Rows at the same time (a segment boundary) are not a hold.
        self.assertEqual(sp.hold_intervals([0.0, 0.0], [1.0, 1.0]), [])

    def test_holds_matter_from_one_percent_of_the_time(self):
        # A 60 min hold after a 0.1 min slide matters; 0.5 % of the time does not, 2 % does.
        self.assertTrue(sp.holds_matter(np.array([0.0, 0.1, 60.1]), np.array([0.0, 1.0, 1.0])))
        for hold, expected in ((0.005, False), (0.02, True)):
            t = np.array([0.0, 1.0 - hold, 1.0])
            self.assertEqual(sp.holds_matter(t, np.array([0.0, 1.0, 1.0])), expected, hold)
        self.assertFalse(sp.holds_matter(np.array([0.0, 1.0]), np.array([0.0, 1.0])))

    def test_peak_at_the_start(self):
        x = np.linspace(0.0, 20.0, 201)
        # A friction peak at 0.04 mm over 20 mm, falling to the steady ratio.
        friction = 0.13 - 0.012 * (1 - np.exp(-x / 2)) - 0.13 * np.exp(-x / 0.01)
        self.assertTrue(sp.peak_at_start(x, friction))
        self.assertFalse(sp.peak_at_start(x, 1 - np.exp(-x)))  # monotone hardening
        self.assertFalse(sp.peak_at_start(x, np.sin(np.pi * x / 20)))  # peak at half the range
        flat = np.minimum(x, 1.0) * (1 - 0.001 * np.minimum(x, 1.0))  # drops < 1 % after it
        self.assertFalse(sp.peak_at_start(x, flat))
        # Compression: magnitudes count (the peak of |stress| at the start of a negative path).
        self.assertTrue(sp.peak_at_start(-x, -friction))


class ReservedRows(unittest.TestCase):
    """A run that did not finish: its series hold reserved rows (NaN) after the valid ones, and
    /progress says how many are valid (docs/scenes.md). Nothing beyond them may be drawn."""

    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="subslip_plots_reserved_")
        self.path = os.path.join(self.dir, "partial.h5")
        with h5py.File(self.path, "w") as f:
            f.attrs.update({"format": "subslip", "scene_kind": "contact", "completed": 0})
            f.create_group("units").attrs.update({"length": "mm"})
            cases = f.create_group("cases")
            cases.attrs["names"] = ["a", "b"]
            a = cases.create_group("a")
            path = np.concatenate([np.linspace(0.0, 1.0, 6), np.full(4, np.nan)])
            for name, values in (("slip_path", path), ("ratio", 0.1 * path),
                                 ("time", path)):
                a.create_dataset(name, data=values, maxshape=(None,), chunks=(4,))
            cases.create_group("b")  # created, never started
            progress = f.create_group("progress")
            progress["rows"] = np.array([6, 0], dtype=np.int64)
            progress["state"] = np.array([1, 0], dtype=np.int64)

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)

    def test_only_valid_rows_and_started_cases(self):
        result = sp.Result(self.path)
        self.assertEqual(result.cases, ["a"])
        ratio = result.case("a").series("ratio")
        self.assertEqual(len(ratio), 6)
        self.assertTrue(np.all(np.isfinite(ratio)))
        out = os.path.join(self.dir, "png")
        run = subprocess.run([sys.executable, os.path.join(HERE, "subslip_plots.py"), self.path,
                              "-o", out], capture_output=True, text=True)
        self.assertEqual(run.returncode, 0, run.stderr)
        self.assertEqual(sorted(os.listdir(out)), ["traction_ratio.pdf", "traction_ratio.png"])


class SweepLabels(unittest.TestCase):
    """Legends name swept values with units: the scene's unit after a bare number, the value
    as written when it was swept with its own unit (docs/scenes.md, "Units")."""

    def test_labels(self):
        directory = tempfile.mkdtemp(prefix="subslip_plots_labels_")
        self.addCleanup(shutil.rmtree, directory, ignore_errors=True)
        path = os.path.join(directory, "sweep.h5")
        with h5py.File(path, "w") as f:
            f.attrs.update({"format": "subslip", "scene_kind": "contact", "completed": 1})
            f.create_group("units").attrs.update({"stress": "MPa", "length": "mm",
                                                  "time": "min"})
            cases = f.create_group("cases")
            values = {"speed=200": 200.0, "speed=1 mm_s": "1 mm/s", "speed=2.5e-3": "2.5e-3"}
            cases.attrs["names"] = list(values)
            for name, value in values.items():
                cases.create_group(name).attrs["sweep:loading[0].slide.speed"] = value
        with sp.Result(path) as result:
            labels = [result.case(n).label() for n in result.cases]
        self.assertEqual(labels, ["speed=200 mm/min", "speed=1 mm/s", "speed=2.5e-3 mm/min"])


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    if head[:8] != PNG_SIGNATURE or head[12:16] != b"IHDR":
        return None
    return struct.unpack(">II", head[16:24])


class LoadingSign(unittest.TestCase):
    """Compression is drawn as positive magnitudes, and the labels say so."""

    def test_sign_of_the_largest_strain(self):
        self.assertEqual(sp.loading_sign([0.0, -0.01, -0.02]), -1.0)
        self.assertEqual(sp.loading_sign([0.0, 0.01, 0.02]), 1.0)
        # Tension after a smaller compression: the largest magnitude decides.
        self.assertEqual(sp.loading_sign([0.0, -0.01, 0.0, 0.03]), 1.0)
        self.assertEqual(sp.loading_sign([np.nan]), 1.0)

    def test_labels(self):
        self.assertEqual(sp.signed_label(("stress", "sigma"), "33", [-1.0, -1.0]),
                         "compressive stress $-\\sigma_{33}$")
        self.assertEqual(sp.signed_label(("strain", "varepsilon"), "33", [1.0]),
                         "strain $\\varepsilon_{33}$")
        self.assertIn("compression positive",
                      sp.signed_label(("stress", "sigma"), "33", [1.0, -1.0]))


class Kept(sp.Output):
    """An Output that keeps the figure instead of saving it, to look at what was drawn."""

    def __init__(self):
        super().__init__(tempfile.gettempdir())
        self.figures = {}

    def save(self, fig, stem):
        self.figures[stem] = fig
        return stem


def core_available():
    try:
        sp.subslip._native.core()
        return True
    except sp.subslip.MissingCore:
        return False


@unittest.skipUnless(os.environ.get("SUBSLIP_BINARY"), "set SUBSLIP_BINARY to the subslip binary")
@unittest.skipUnless(core_available(), "the von Mises panels need the compiled core: set "
                     "SUBSLIP_CORE_DIR")
class Pictures(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp(prefix="subslip_plots_")
        cls.addClassCleanup(shutil.rmtree, cls.dir, ignore_errors=True)  # also if setUp fails
        cls.results = {}
        for scene in ("crystal_small", "contact_small", "single_crystal_euler", "contact_hold",
                      "crystal_hold", "crystal_compression"):
            out = os.path.join(cls.dir, scene + ".h5")
            subprocess.run([os.environ["SUBSLIP_BINARY"], "run", "-q", "-o", out,
                            os.path.join(SOURCE, "tests", "data", "post", scene + ".yaml")],
                           check=True)
            cls.results[scene] = out

    def draw(self, scene, *extra):
        out = os.path.join(self.dir, scene + "_" + "_".join(extra) + "_png")
        run = subprocess.run([sys.executable, os.path.join(HERE, "subslip_plots.py"),
                              self.results[scene], "-o", out, *extra],
                             capture_output=True, text=True)
        return run, out

    def assert_pictures(self, directory, names):
        """The PNG files `names`, each beside its PDF (the default formats)."""
        pdfs = [os.path.splitext(n)[0] + ".pdf" for n in names]
        self.assertEqual(sorted(os.listdir(directory)), sorted(names + pdfs))
        for name in names:
            path = os.path.join(directory, name)
            size = png_size(path)
            self.assertIsNotNone(size, f"{name} is not a PNG")
            self.assertGreater(min(size), 200, name)
            self.assertGreater(os.path.getsize(path), 10000, f"{name} is nearly empty")

    def test_crystal_pictures(self):
        run, out = self.draw("crystal_small")
        self.assertEqual(run.returncode, 0, run.stderr)
        cases = ["L_2__2_=1.0e-3", "L_2__2_=1.0e-1"]
        self.assert_pictures(out, ["stress_strain.png"] +
                             [f"slip_activity_{c}.png" for c in cases] +
                             [f"pole_figures_{c}.png" for c in cases])
        self.assertIn("traction ratio: not a contact result, skipped", run.stderr)

    def test_contact_pictures(self):
        run, out = self.draw("contact_small")
        self.assertEqual(run.returncode, 0, run.stderr)
        self.assert_pictures(out, ["traction_ratio.png"])
        self.assertIn("stress-strain: not a crystal result, skipped", run.stderr)

    def test_one_case_and_missing_data(self):
        run, out = self.draw("single_crystal_euler", "--case", "base")
        self.assertEqual(run.returncode, 0, run.stderr)
        self.assert_pictures(out, ["pole_figures_base.png"])
        self.assertIn("slip activity (base): no grains/slip_rate or grains/slip", run.stderr)
        run, _ = self.draw("contact_small", "--case", "nope")
        self.assertEqual(run.returncode, 2)
        self.assertIn("no case 'nope'", run.stderr)

    def test_formats_and_resolution(self):
        # --format pdf / svg: the same pictures as vector files; --dpi scales a PNG's pixels.
        for fmt, signature in (("pdf", b"%PDF-"), ("svg", b"<svg")):
            run, out = self.draw("contact_small", "--format", fmt)
            self.assertEqual(run.returncode, 0, run.stderr)
            self.assertEqual(os.listdir(out), [f"traction_ratio.{fmt}"])
            with open(os.path.join(out, f"traction_ratio.{fmt}"), "rb") as f:
                self.assertIn(signature, f.read(4096))
        run, out = self.draw("contact_small", "--format", "svg,png")
        self.assertEqual(sorted(os.listdir(out)), ["traction_ratio.png", "traction_ratio.svg"])
        run, _ = self.draw("contact_small", "--format", "png,gif")
        self.assertEqual(run.returncode, 2)
        self.assertIn("give png, pdf and/or svg", run.stderr)
        # 300 dpi by default (a talk's); --dpi 150 halves the pixels; --docs-size: PNG only at
        # 100 dpi, a third of them.
        _, default = self.draw("contact_small")
        _, half = self.draw("contact_small", "--dpi", "150")
        _, docs = self.draw("contact_small", "--docs-size")
        width, height = png_size(os.path.join(default, "traction_ratio.png"))
        self.assertEqual((width, height), (3300, 1290))  # 11 x 4.3 inches
        self.assertEqual(png_size(os.path.join(half, "traction_ratio.png")),
                         (width // 2, height // 2))
        self.assertEqual(os.listdir(docs), ["traction_ratio.png"])
        self.assertEqual(png_size(os.path.join(docs, "traction_ratio.png")),
                         (width // 3, height // 3))

    def test_legends_name_swept_values_with_units(self):
        run, out = self.draw("contact_small", "--format", "svg")
        self.assertEqual(run.returncode, 0, run.stderr)
        with open(os.path.join(out, "traction_ratio.svg"), encoding="utf-8") as f:
            svg = f.read()
        self.assertIn("speed=200 mm/min", svg)

    def svg(self, scene, picture):
        run, out = self.draw(scene, "--format", "svg")
        self.assertEqual(run.returncode, 0, run.stderr)
        with open(os.path.join(out, picture + ".svg"), encoding="utf-8") as f:
            return f.read()

    def test_a_hold_gets_a_time_axis(self):
        # contact_hold.yaml holds 60 min between two slides of 0.02 and 0.03 min: against the
        # sliding distance the hour is a vertical line, so a third panel runs against time.
        svg = self.svg("contact_hold", "traction_ratio")
        self.assertEqual(svg.count('<g id="axes_'), 3)
        self.assertIn("time [min]", svg)
        self.assertIn("hold", svg)
        with sp.Result(self.results["contact_hold"]) as result:
            t = result.case("base").time()
            self.assertAlmostEqual(t[-1] - t[0], 60.05, places=9)  # the hold, in minutes
        # Without holds: the two sliding-distance panels only.
        svg = self.svg("contact_small", "traction_ratio")
        self.assertEqual(svg.count('<g id="axes_'), 2)
        self.assertNotIn("time [", svg)
        self.assertIn("sliding distance [mm], logarithmic", svg)

    def test_crystal_peak_and_hold_panels(self):
        # crystal_hold.yaml softens after yield (a peak near 0.1 % of 2 % strain) and then holds
        # 100 s: a logarithmic strain panel and a time panel.
        svg = self.svg("crystal_hold", "stress_strain")
        self.assertEqual(svg.count('<g id="axes_'), 4)
        self.assertIn("logarithmic", svg)
        self.assertIn("time [s]", svg)
        self.assertIn("stress $\\sigma_{33}$ [MPa]", svg)
        # crystal_small.yaml hardens monotonically without holds: the two usual panels.
        svg = self.svg("crystal_small", "stress_strain")
        self.assertEqual(svg.count('<g id="axes_'), 2)
        self.assertNotIn("logarithmic", svg)
        self.assertNotIn("time [", svg)

    def test_compression_is_drawn_as_positive_magnitudes(self):
        kept = Kept()
        with sp.Result(self.results["crystal_compression"]) as result:
            sp.plot_stress_strain(result, result.cases, kept)
            sp.plot_slip_activity(result, "base", kept)
            strain = result.case("base").series("macro/strain")[:, 2, 2]
            stress = result.case("base").series("macro/stress")[:, 2, 2]
        self.assertLess(strain[-1], -0.019)  # the file holds the signed values
        self.assertLess(stress[-1], -30.0)
        fig = kept.figures["stress_strain"]
        x, y = fig.axes[0].lines[0].get_data()
        np.testing.assert_array_equal(x, -strain)
        np.testing.assert_array_equal(y, -stress)
        self.assertEqual(fig.axes[0].get_xlabel(), "compressive strain $-\\varepsilon_{33}$ [1]")
        self.assertEqual(fig.axes[0].get_ylabel(), "compressive stress $-\\sigma_{33}$ [MPa]")
        self.assertIn("compression", fig.axes[0].lines[0].get_label())
        activity = kept.figures["slip_activity_base"]
        x, _ = activity.axes[0].lines[0].get_data()
        self.assertGreater(np.min(x[1:]), 0.0)
        self.assertTrue(activity.axes[0].get_xlabel().startswith("compressive strain"))
        # Tension keeps its signs and plain labels.
        kept = Kept()
        with sp.Result(self.results["crystal_small"]) as result:
            sp.plot_stress_strain(result, result.cases, kept)
        self.assertEqual(kept.figures["stress_strain"].axes[0].get_ylabel(),
                         "stress $\\sigma_{33}$ [MPa]")

    def test_friction_legend_is_on_the_logarithmic_panel(self):
        kept = Kept()
        with sp.Result(self.results["contact_small"]) as result:
            sp.plot_traction_ratio(result, result.cases, kept)
        linear, logarithmic = kept.figures["traction_ratio"].axes
        self.assertEqual(logarithmic.get_xscale(), "log")
        self.assertIsNone(linear.get_legend())
        self.assertEqual([t.get_text() for t in logarithmic.get_legend().get_texts()],
                         ["speed=1 mm/min", "speed=200 mm/min"])

    def test_pole_figures_have_sample_axes_and_density(self):
        kept = Kept()
        with sp.Result(self.results["crystal_compression"]) as result:
            sp.plot_pole_figures(result, "base", kept)
        fig = kept.figures["pole_figures_base"]
        pole_axes, bar = fig.axes[:6], fig.axes[6]
        self.assertEqual(len(fig.axes), 7, "2 x 3 pole figures and one colour bar")
        for ax in pole_axes:
            texts = {t.get_text() for t in ax.texts}
            self.assertTrue({"RD", "TD", "ND"} <= texts, texts)
            self.assertTrue(ax.collections, "density contours")
        self.assertIn("MRD", bar.get_ylabel())
        self.assertIn("x = RD, y = TD, z = ND", fig._suptitle.get_text())

    def test_loading_component_is_the_prescribed_one(self):
        # Tension along z with free lateral L11, L22 (which change every step): 33.
        result = sp.Result(self.results["crystal_small"])
        self.assertEqual(len(result.cases), 2)
        for name in result.cases:
            self.assertEqual(result.case(name).loading_component(), (2, 2))

    def test_stored_quaternion_gives_the_euler_grains_poles(self):
        # The grain of single_crystal_euler.yaml is at Bunge (90, 30, 0) deg. subslip converted
        # that to the stored quaternion; the script must turn it back into the same g, and put
        # crystal direction c at g^T c: [100] -> row 0 of g = sample +y, [001] -> row 2 =
        # (sin 30, 0, cos 30), [010] -> row 1 = (-cos 30, 0, sin 30).
        g = bunge_matrix(90, 30, 0)
        np.testing.assert_allclose(g[0], [0, 1, 0], atol=1e-15)
        with h5py.File(self.results["single_crystal_euler"], "r") as f:
            q = f["cases/base/grains/initial_orientation"][:]
        np.testing.assert_allclose(sp.quaternion_to_matrix(q)[0], g, atol=1e-12)
        x, y = sp.pole_figure_points(q, sp.cubic_family((1, 0, 0)))
        expected = [project(v) for v in (g[0], -g[0], g[2], g[1])]  # -g[1] has z < 0
        ex, ey = np.array(expected).T
        np.testing.assert_allclose(points(x, y), points(ex, ey), atol=1e-9)


if __name__ == "__main__":
    unittest.main()
