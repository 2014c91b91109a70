#!/usr/bin/python3
"""The coefficients of the batches' arcsine (law::closed_form::arcsine_to_quarter_pi in
include/subslip/law/closed_form.hpp), and how close the fit is.

    /usr/bin/python3 scripts/fit_arcsine.py

asin(h) for h in [0, 2^-1/2] is written h + h^3 P(h^2); P (degree 19) is the Chebyshev fit of
(asin(h)/h - 1)/h^2 over t = h^2 in [0, 1/2], computed at 50 digits. The script prints P's
coefficients (highest power first, each the shortest decimal that reads back as the double) and
the largest error of the fit evaluated in double precision as the C++ does (Horner in t), in
units in the last place of asin(h), and of its slope relative to 1/sqrt(1 - h^2), both against
50-digit values. Needs mpmath (python3-mpmath) and numpy.
"""

import mpmath as mp
import numpy as np

DEGREE = 19
mp.mp.dps = 50


def correction(t):
    """(asin(h)/h - 1)/h^2 at t = h^2; 1/6 at t = 0."""
    if t == 0:
        return mp.mpf(1) / 6
    h = mp.sqrt(t)
    return (mp.asin(h) / h - 1) / t


def evaluate(coefficients, h):
    """The fit in double precision, in the C++'s order of operations."""
    t = h * h
    p = coefficients[0]
    for c in coefficients[1:]:
        p = p * t + c
    return h + h * t * p


def main():
    fitted, _ = mp.chebyfit(correction, [0, mp.mpf("0.5")], DEGREE + 1, error=True)
    coefficients = [float(c) for c in fitted]
    print("coefficients (highest power first):")
    print(", ".join(repr(c) for c in coefficients))

    points = np.concatenate([np.linspace(0.0, 2**-0.5, 20001), np.geomspace(1e-12, 2**-0.5, 5001)])
    worst_ulp = 0.0
    for h in points:
        exact = mp.asin(mp.mpf(h))
        if exact == 0:
            continue
        error = abs(mp.mpf(evaluate(coefficients, h)) - exact) / np.spacing(float(exact))
        worst_ulp = max(worst_ulp, float(error))
    print(f"largest error of asin: {worst_ulp:.3f} ulp over {len(points)} points")

    polynomial = np.poly1d([mp.mpf(c) for c in coefficients])
    slope = polynomial.deriv()
    worst_slope = 0.0
    for h in np.linspace(0.0, 2**-0.5, 3001):
        t = mp.mpf(h) ** 2
        fit_slope = 1 + 3 * t * polynomial(t) + 2 * t * t * slope(t)
        exact = 1 / mp.sqrt(1 - t)
        worst_slope = max(worst_slope, float(abs(fit_slope - exact) / exact))
    print(f"largest relative error of its slope: {worst_slope:.2e}")


if __name__ == "__main__":
    main()
