"""Orientations of a result file as pole-figure and inverse-pole-figure points.

The file stores each orientation as the unit quaternion (w, x, y, z) of g with
v_crystal = g v_sample (passive, Rowenhorst et al. 2015, P = -1; include/subslip/crystal/
rotation.hpp). So a crystal direction c points along g^T c in the sample (pole figures), and a
sample direction d has the crystal components g d (inverse pole figures).

Projections map the upper hemisphere (z >= 0) onto the unit disk: equal-area (Lambert,
(x, y) / sqrt(1 + z), the default: densities compare by area) or stereographic
((x, y) / (1 + z), angles preserved; the usual drawing of the standard triangle).
"""

import itertools
import math

import numpy as np


def quaternion_to_matrix(q):
    """Orientation matrices g (..., 3, 3) of quaternions q (..., 4) = (w, x, y, z), normalised
    first. A rotation by omega about n is q = (cos(omega/2), n sin(omega/2)); e.g. 90 deg
    about z gives g = [[0, 1, 0], [-1, 0, 0], [0, 0, 1]]."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    g = np.empty(q.shape[:-1] + (3, 3))
    g[..., 0, 0] = w * w + x * x - y * y - z * z
    g[..., 0, 1] = 2.0 * (x * y + w * z)
    g[..., 0, 2] = 2.0 * (x * z - w * y)
    g[..., 1, 0] = 2.0 * (x * y - w * z)
    g[..., 1, 1] = w * w - x * x + y * y - z * z
    g[..., 1, 2] = 2.0 * (y * z + w * x)
    g[..., 2, 0] = 2.0 * (x * z + w * y)
    g[..., 2, 1] = 2.0 * (y * z - w * x)
    g[..., 2, 2] = w * w - x * x - y * y + z * z
    return g


def matrix_to_quaternion(g):
    """Quaternions (..., 4) with w >= 0 of orientation matrices g (..., 3, 3): the inverse of
    quaternion_to_matrix (the largest of w, x, y, z is found first, for accuracy)."""
    g = np.asarray(g, dtype=float)
    trace = np.trace(g, axis1=-2, axis2=-1)
    # 4 w^2, 4 x^2, 4 y^2, 4 z^2 from the diagonal; the off-diagonal sums give the products.
    squares = np.stack([1.0 + trace, 1.0 + 2.0 * g[..., 0, 0] - trace,
                        1.0 + 2.0 * g[..., 1, 1] - trace, 1.0 + 2.0 * g[..., 2, 2] - trace], -1)
    products = {  # 4 * (product of two quaternion components), from quaternion_to_matrix
        (0, 1): g[..., 1, 2] - g[..., 2, 1], (0, 2): g[..., 2, 0] - g[..., 0, 2],
        (0, 3): g[..., 0, 1] - g[..., 1, 0], (1, 2): g[..., 0, 1] + g[..., 1, 0],
        (1, 3): g[..., 0, 2] + g[..., 2, 0], (2, 3): g[..., 1, 2] + g[..., 2, 1]}
    largest = np.argmax(squares, axis=-1)
    q = np.empty(g.shape[:-2] + (4,))
    for k in range(4):
        pick = largest == k
        qk = np.sqrt(np.maximum(squares[pick, k], 0.0)) / 2.0  # |component k|
        q[pick, k] = qk
        for j in range(4):
            if j != k:
                q[pick, j] = products[tuple(sorted((k, j)))][pick] / (4.0 * qk)
    return q * np.where(q[..., :1] < 0.0, -1.0, 1.0)


def cubic_family(hkl):
    """All unit vectors of the cubic form {hkl}, both signs (permutations and sign changes)."""
    vectors = set()
    for perm in itertools.permutations(hkl):
        for signs in itertools.product((1, -1), repeat=3):
            vectors.add(tuple(s * p for s, p in zip(signs, perm)))
    v = np.array(sorted(vectors), dtype=float)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def hexagonal_family(name):
    """Unit plane normals of {0001}, {10-10} or {11-20}, both signs, in subslip's hexagonal
    lattice frame (a1 along x, c along z; include/subslip/crystal/slip_systems.hpp)."""
    if name == "0001":
        return np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    start = {"10-10": 30.0, "11-20": 0.0}[name]
    angles = np.radians(start + 60.0 * np.arange(6))
    return np.stack([np.cos(angles), np.sin(angles), np.zeros(6)], axis=1)


def pole_families(lattice):
    """The three standard (label, unit vectors) pole families of a lattice ("cubic" or
    "hcp"; anything else is drawn as cubic)."""
    if lattice == "hcp":
        return [("{0001}", hexagonal_family("0001")), ("{10-10}", hexagonal_family("10-10")),
                ("{11-20}", hexagonal_family("11-20"))]
    return [("{111}", cubic_family((1, 1, 1))), ("{100}", cubic_family((1, 0, 0))),
            ("{110}", cubic_family((1, 1, 0)))]


def sample_directions(g, crystal_vectors):
    """Sample-frame components g^T c of crystal directions c: (grains, vectors, 3)."""
    g = np.asarray(g).reshape(-1, 3, 3)
    return np.einsum("gji,vj->gvi", g, np.asarray(crystal_vectors, dtype=float))


def project(v, projection="equal_area"):
    """(X, Y) on the unit disk of upper-hemisphere unit vectors v (..., 3), z in [0, 1]."""
    v = np.asarray(v, dtype=float).reshape(-1, 3)
    z = np.clip(v[:, 2], 0.0, 1.0)
    if projection == "equal_area":
        scale = 1.0 / np.sqrt(1.0 + z)
    elif projection == "stereographic":
        scale = 1.0 / (1.0 + z)
    else:
        raise ValueError(f"projection '{projection}': use 'equal_area' or 'stereographic'")
    return v[:, 0] * scale, v[:, 1] * scale


def upper_hemisphere_projection(v, projection="equal_area"):
    """The projected upper-hemisphere vectors among v (..., 3): z = 1 at the centre, z = 0 on
    the rim. Lower-hemisphere vectors are dropped rather than mirrored, since pole families
    hold both signs; a pole on the equator is kept with both signs (the two rim points)."""
    v = np.asarray(v, dtype=float).reshape(-1, 3)
    return project(v[v[:, 2] > -1e-9], projection)


def pole_figure_points(quaternions, crystal_vectors, projection="equal_area"):
    """Projected (X, Y), sample frame, of the poles `crystal_vectors` (both signs, as
    cubic_family gives them) of every orientation (quaternions (..., 4))."""
    g = quaternion_to_matrix(quaternions)
    return upper_hemisphere_projection(sample_directions(g, crystal_vectors), projection)


def crystal_directions(quaternions, sample_direction):
    """Crystal-frame unit components g d of one sample direction d for every orientation:
    (grains, 3)."""
    d = np.asarray(sample_direction, dtype=float)
    d = d / np.linalg.norm(d)
    return quaternion_to_matrix(quaternions).reshape(-1, 3, 3) @ d


def cubic_standard_triangle(v):
    """Crystal directions v (n, 3) moved into the standard triangle [001]-[101]-[111] by the
    cubic symmetry with inversion (m-3m): z >= x >= y >= 0. The 48 operations permute and
    change signs of the components, so the triangle's point has the sorted absolute values."""
    a = np.sort(np.abs(np.asarray(v, dtype=float)), axis=1)  # smallest, middle, largest
    return np.stack([a[:, 1], a[:, 0], a[:, 2]], axis=1)


def hexagonal_standard_triangle(v):
    """Crystal directions v (n, 3) moved into the triangle [0001]-[2-1-10]-[10-10] by 6/mmm
    symmetry with inversion: z >= 0 and azimuth in [0, 30] deg from a1 (x)."""
    v = np.asarray(v, dtype=float)
    z = np.abs(v[:, 2])
    r = np.hypot(v[:, 0], v[:, 1])
    phi = np.mod(np.arctan2(v[:, 1], v[:, 0]), np.pi / 3.0)  # six-fold axis
    phi = np.minimum(phi, np.pi / 3.0 - phi)  # mirror planes every 30 deg
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def standard_triangle_outline(lattice="cubic", projection="equal_area", points=60):
    """(X, Y) of the closed outline of the standard triangle inverse_pole_figure_points
    fills, for drawing: cubic [001] -> [101] -> [111] -> [001], hcp [0001] -> [2-1-10] ->
    [10-10] -> [0001]. The edges are great circles, sampled at `points` points each."""
    t = np.linspace(0.0, 1.0, points)[:, None]
    if lattice == "hcp":
        a1, m1 = np.array([1.0, 0.0, 0.0]), np.array([math.sqrt(0.75), 0.5, 0.0])
        corners = [np.array([0.0, 0.0, 1.0]), a1, m1]
    else:
        corners = [np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 1.0]), np.ones(3)]
    edges = [(1.0 - t) * a + t * b for a, b in zip(corners, corners[1:] + corners[:1])]
    v = np.concatenate(edges)
    return project(v / np.linalg.norm(v, axis=1, keepdims=True), projection)


def inverse_pole_figure_points(quaternions, sample_direction=(0.0, 0.0, 1.0), lattice="cubic",
                               projection="equal_area"):
    """Projected (X, Y) of a sample direction (default z) in the crystal frame of every
    orientation, reduced to the standard triangle of the lattice ("cubic": [001] at the
    centre, [101] on the x axis at the rim, [111] between; "hcp": [0001] at the centre,
    a1 = [2-1-10] on the x axis). Another lattice: the upper hemisphere, unreduced."""
    v = crystal_directions(quaternions, sample_direction)
    if lattice == "cubic":
        v = cubic_standard_triangle(v)
    elif lattice == "hcp":
        v = hexagonal_standard_triangle(v)
    else:
        v = v * np.where(v[:, 2:3] < 0.0, -1.0, 1.0)  # d and -d are the same axis
    return project(v, projection)


def kernel_concentration(half_width_deg):
    """The concentration kappa of the von Mises-Fisher kernel exp(kappa cos(angle)) that falls
    to half its peak `half_width_deg` away from it."""
    return math.log(2.0) / (1.0 - math.cos(math.radians(half_width_deg)))


def equal_area_inverse(X, Y):
    """Upper-hemisphere unit vectors (..., 3) of equal-area points (X, Y) with X^2 + Y^2 <= 1:
    the inverse of project(v, "equal_area"), z = 1 - r^2."""
    X, Y = np.asarray(X, dtype=float), np.asarray(Y, dtype=float)
    r2 = np.minimum(X * X + Y * Y, 1.0)
    scale = np.sqrt(2.0 - r2)
    return np.stack([X * scale, Y * scale, 1.0 - r2], axis=-1)


def pole_density(quaternions, crystal_vectors, weights=None, half_width_deg=10.0,
                 resolution=101):
    """The pole density of `crystal_vectors` (both signs, as cubic_family gives them) of the
    orientations, in multiples of a random distribution (MRD), on a grid of the equal-area
    projection: (X, Y, mrd), each (resolution, resolution), mrd NaN outside the unit disk.

    Every pole p spreads as a von Mises-Fisher kernel on the sphere, C exp(kappa x.p) with
    C = kappa / (4 pi sinh kappa) (its integral is 1), kappa from the half-width
    (kernel_concentration); a random texture gives 1 everywhere, and since the projection is
    equal-area the mean over the disk is 1 for any texture. The kernel lives on the sphere, so
    poles near the rim count on both sides of it (p and -p), as they must."""
    g = quaternion_to_matrix(quaternions).reshape(-1, 3, 3)
    w = np.ones(len(g)) if weights is None else np.asarray(weights, dtype=float)
    poles = sample_directions(g, crystal_vectors).reshape(len(g), -1, 3)
    pole_weights = np.repeat(w / (np.sum(w) * poles.shape[1]), poles.shape[1])
    poles = poles.reshape(-1, 3)
    kappa = kernel_concentration(half_width_deg)
    t = np.linspace(-1.0, 1.0, resolution)
    X, Y = np.meshgrid(t, t)
    inside = X * X + Y * Y <= 1.0
    x = equal_area_inverse(X[inside], Y[inside])
    mrd = np.full(X.shape, np.nan)
    values = np.empty(len(x))
    # 4 pi C exp(kappa c) = 2 kappa exp(kappa (c - 1)) / (1 - exp(-2 kappa)): no overflow.
    factor = 2.0 * kappa / -math.expm1(-2.0 * kappa)
    for start in range(0, len(x), 512):  # blocks: (512, poles) at a time
        c = x[start:start + 512] @ poles.T
        values[start:start + 512] = factor * (np.exp(kappa * (c - 1.0)) @ pole_weights)
    mrd[inside] = values
    return X, Y, mrd
