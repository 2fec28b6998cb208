"""One rule for "the same value of a parameter", wherever branches, maps, scans or branch
points are grouped or matched by the values of the parameters they hold fixed.

Values of a fixed parameter that are meant to be the same come from one run-file value or
expression (equal, or an ulp apart where written differently: ``"pi^2/4"`` and
``2.4674011002723395``), from a start continued to a value (which it then holds exactly), or
from a value moved by whole periods (a few ulps of the period off). Values meant to differ
are given apart by the user, to the digits they write. SAME_VALUE_RTOL lies between: a
million ulps, which no rounding reaches, and a billionth, which no value a user writes to
nine digits comes within. It is relative to the values themselves (and to the period, for
a periodic parameter compared modulo it), so it means the same for a parameter of any
size: 1e-12 and 2e-12 are different values, 1e12 and 1e12 + 1 the same.
"""

from __future__ import annotations

import math
import numbers

SAME_VALUE_RTOL = 1e-9


def real_number(v) -> bool:
    """Whether ``v`` is a real number a user may give for a value or an option: a Python int
    or float, or a numpy scalar such as ``np.int64`` (from ``np.arange``) or ``np.float32``
    (numbers.Real), but not a bool (an int to Python, never meant as a number here)."""
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def plain(v):
    """A numpy scalar as the Python int or float it holds (what JSON and TOML write); any
    other value as it is."""
    item = getattr(v, "item", None)
    return item() if isinstance(v, numbers.Number) and callable(item) else v


def same_value(a: float, b: float, period: float | None = None) -> bool:
    """Whether ``a`` and ``b`` are the same value of a parameter: within SAME_VALUE_RTOL of
    the larger of them, modulo ``period`` if given (then also relative to the period, the
    size of a value's copies)."""
    d = a - b
    scale = max(abs(a), abs(b))
    if period:
        d = math.remainder(d, period)
        scale = max(scale, abs(period))
    return abs(d) <= SAME_VALUE_RTOL * scale
