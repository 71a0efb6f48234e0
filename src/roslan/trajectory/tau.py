"""Closed-form tau-theory gaps (docs/design.md §1, corrected equations).

Every gap is written in terms of the normalised remaining time ``s = 1 - t/T`` in
[0, 1], so no negative gap is ever raised to a fractional power:

    g(t)   = g0 * s**n
    g'(t)  = -g0 * n / T * s**(n - 1)
    g''(t) = g0 * n * (n - 1) / T**2 * s**(n - 2)

with ``n = 1/k`` for the main (height) gap and ``n = 1/(k*kappa)`` for a gap coupled
with ratio ``kappa``. Powers with a negative exponent (the derivatives of warned,
hard-landing parameter sets) are evaluated at ``max(s, S_FLOOR)`` so that the value
at touchdown is the finite value an instant (``S_FLOOR * T``) before it, never inf.
"""

from __future__ import annotations

from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

__all__ = ["S_FLOOR", "Terminal", "classify", "exponent", "gap", "powers", "safe_pow"]

F64 = NDArray[np.float64]

S_FLOOR = 1e-9
"""Smallest ``s`` used for negative powers (= 1e-9 of the touchdown time)."""

_EPS = 1e-12


class Terminal(StrEnum):
    """How a gap closes at touchdown, from its exponent ``n`` (docs/design.md §1)."""

    SOFT = "soft"  # rate -> 0, acceleration -> 0           (n > 2, i.e. k*kappa < 0.5)
    CONSTANT_DECELERATION = "constant_deceleration"  # rate -> 0, acceleration constant (n = 2)
    UNBOUNDED_DECELERATION = "unbounded_deceleration"  # rate -> 0, |acc| -> inf (1 < n < 2)
    NONZERO_RATE = "nonzero_rate"  # closes at constant rate: contact with speed (n = 1)
    NONE = "none"  # the gap is zero from the start: nothing to close

    @property
    def bounded(self) -> bool:
        return self in (Terminal.SOFT, Terminal.CONSTANT_DECELERATION, Terminal.NONE)


def classify(product: float, g0: float = 1.0) -> Terminal:
    """Terminal behaviour of a gap with ``k*kappa = product`` (``k`` alone for the main gap)."""
    if g0 == 0.0:
        return Terminal.NONE
    if product < 0.5 - _EPS:
        return Terminal.SOFT
    if abs(product - 0.5) <= _EPS:
        return Terminal.CONSTANT_DECELERATION
    if product < 1.0 - _EPS:
        return Terminal.UNBOUNDED_DECELERATION
    return Terminal.NONZERO_RATE


def exponent(product: float) -> float:
    """Closure exponent ``n = 1/product`` (product = k or k*kappa), snapped to exactly 1
    or 2 where :func:`classify` calls the product 1 or 0.5, so numbers and labels agree."""
    if abs(product - 1.0) <= _EPS:
        return 1.0
    if abs(product - 0.5) <= _EPS:
        return 2.0
    return 1.0 / product


def safe_pow(s: F64, e: float) -> F64:
    """``s**e`` for s in [0, 1]: exact (0**0 = 1, 0**e = 0) for e >= 0, floored for e < 0."""
    if e == 0.0:
        return np.ones_like(s)
    if e == 1.0:
        return s.copy()
    if e == 2.0:
        return s * s
    if e == 0.5:
        return np.sqrt(s)
    if e > 0.0:
        return np.power(s, e)
    return np.power(np.maximum(s, S_FLOOR), e)


def powers(s: F64, n: float) -> tuple[F64, F64, F64]:
    """``(s**n, s**(n-1), s**(n-2))`` for s in [0, 1] and n >= 1, with one ``pow`` call.

    The lower power is computed and the others follow by multiplying with s, which
    stays exact at s = 0 (where ``s**(n-2)`` is finite for n >= 2). For 1 <= n < 2
    (warned, unbounded-deceleration parameters) ``s**(n-1)`` is a second exact power
    and only ``s**(n-2)`` is floored at :data:`S_FLOOR`.
    """
    if n >= 2.0:
        p2 = safe_pow(s, n - 2.0)
        p1 = p2 * s
        return p1 * s, p1, p2
    p1 = safe_pow(s, n - 1.0)
    # linear closure (n = 1): no second derivative at all
    p2 = np.zeros_like(s) if abs(n - 1.0) <= _EPS else safe_pow(s, n - 2.0)
    return p1 * s, p1, p2


def gap(g0: float, n: float, T: float, s: F64) -> tuple[F64, F64, F64]:
    """Gap value, rate and second derivative at normalised remaining times ``s``.

    Args:
        g0: initial gap (any sign; units of the gap).
        n: closure exponent (1/k or 1/(k kappa)), n >= 1.
        T: touchdown time (s).
        s: (N,) values of 1 - t/T in [0, 1].
    Returns:
        three (N,) arrays: g, dg/dt, d2g/dt2.
    """
    if g0 == 0.0:
        z = np.zeros_like(s)
        return z, z.copy(), z.copy()
    p0, p1, p2 = powers(s, n)
    return g0 * p0, (-g0 * n / T) * p1, (g0 * n * (n - 1.0) / (T * T)) * p2
