"""Material points of the core (include/subslip/material_point.hpp) along given paths.

A point takes the parameters of a scene's case, so that its names, units and checks are a
scene's (docs/scenes.md): a contact point the case's law, stiffness and update
(`integrator.method`), a grain or a Taylor aggregate the case's phase and orientations (and
weights). The scene's loading is not used, but `steps()` gives it as the drivers step it, to be
driven as it is or changed. Arrays in, dicts of numpy arrays out; row k of each is the point
after step k, and "state" the last state, which continues a path when given back as `state`.
The interpreter keeps running while the core computes.
"""

import numpy as np

from ._native import core
from .scene_source import scene_source


def _rows(values, shape, n, what):
    """`values` as float64 of shape (n, *shape), one value broadcast to every step."""
    a = np.asarray(values, dtype=np.float64)
    if a.shape == tuple(shape):
        a = np.broadcast_to(a, (n, *shape))
    if a.shape != (n, *shape):
        raise ValueError(f"{what}: shape {a.shape}; expected {(n, *shape)} or {tuple(shape)}")
    return np.ascontiguousarray(a)


def _dt(dt):
    a = np.asarray(dt, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"dt: shape {a.shape}; expected (n,), one length a step")
    return np.ascontiguousarray(a)


class ContactPoint:
    """A frictional contact point with the law, stiffness and update of a contact scene's case
    (`case`: its name, needed only when the scene sweeps)."""

    def __init__(self, scene, case=None):
        name, text = scene_source(scene)
        self._point = core().ContactPoint(name, text, case or "")

    def initial_state(self):
        """The state before the first step: a dict of the traction, slip, mu, r_s, ..."""
        return self._point.initial_state()

    def steps(self):
        """The case's loading as fixed increments: (slip increments (n, 2) [length], normal
        traction at each step's end (n,) [stress], dt (n,) [time])."""
        return self._point.steps()

    def along_path(self, slip_increments, normal_traction, dt, state=None):
        """Updates the point over the steps: slip increments du_t (n, 2), normal traction at
        each step's end (n,) or one value, dt (n,). Returns time, slip, traction (n, 2),
        normal_traction, mu, r_s, r, vp_slip, the tangent d f_t / d (du_t, f_n) (n, 2, 3), the
        Newton iterations, and "state"."""
        dt = _dt(dt)
        n = len(dt)
        return self._point.along_path(_rows(slip_increments, (2,), n, "slip increments"),
                                      _rows(normal_traction, (), n, "normal traction"), dt,
                                      state)


class _CrystalPoint:
    def steps(self):
        """The case's loading as fixed increments: (velocity gradients (n, 3, 3) [1/time],
        dt (n,) [time]); mixed control (stress components prescribed) has no such path."""
        return self._point.steps()

    def initial_state(self):
        """The virgin state: a dict of arrays with a leading grain axis (stress (G, 6), lattice
        frame, Mandel; orientation (G, 3, 3); mu, r_s, slip, rate, ... (G, N); trend_step)."""
        return self._point.initial_state()

    def along_path(self, velocity_gradients, dt, state=None):
        """Updates the point over the steps: velocity gradients L (n, 3, 3) (sample frame) or
        one L, dt (n,). Returns the Cauchy stress (n, 3, 3) (sample frame; a Taylor point's
        volume average), the tangent d sigma / d (D dt) (n, 6, 6, Mandel), the Newton
        iterations and "state"."""
        dt = _dt(dt)
        return self._point.along_path(_rows(velocity_gradients, (3, 3), len(dt),
                                            "velocity gradients"), dt, state)


class GrainPoint(_CrystalPoint):
    """Grain `grain` of a crystal scene's case: its phase and orientation."""

    def __init__(self, scene, case=None, grain=0):
        name, text = scene_source(scene)
        self._point = core().GrainPoint(name, text, case or "", grain)

    def sensitivities_along_path(self, velocity_gradients, dt):
        """along_path from the initial state, with the forward sensitivities of the path to the
        phase's law constants, tau0 and initial_mu ("parameters": their names, the last axis of
        each derivative): "d_stress" (n, 3, 3, 10) of the stress (sample frame), "d_mu",
        "d_r_s", "d_slip" (n, N, 10) [output unit / parameter unit]. The phase's slip systems
        must share one law, tau0 and initial_mu, without plane pressure (ValueError otherwise);
        docs/calibration.md, "Sensitivities of a grain"."""
        dt = _dt(dt)
        return self._point.sensitivities_along_path(_rows(velocity_gradients, (3, 3), len(dt),
                                                          "velocity gradients"), dt)


class TaylorPoint(_CrystalPoint):
    """A crystal scene's case as one Taylor material point: every grain (orientations and
    weights) under the point's velocity gradient, stress and tangent volume averages."""

    def __init__(self, scene, case=None):
        name, text = scene_source(scene)
        self._point = core().TaylorPoint(name, text, case or "")

    @property
    def grain_count(self):
        return self._point.grain_count


def increment_lengths(duration, increments, growth=1.0):
    """The increment lengths of a scene's segment: `increments` lengths in geometric
    progression with ratio `growth`, summing to `duration` exactly (as the drivers take them)."""
    return core().increment_lengths(duration, increments, growth)
