"""An isoperimetric constraint whose rate contains a rotation's strains (issue 47: its
integration by parts for rotation coordinates; docs/energy.md, "Constraints with strains"):
a rod whose total of ``u3 + al u1^2`` is prescribed, ``tw' = u3 + al u1^2``, ``tw(1) = T``.

The derived linearised constraint ``int g.w ds + d0.w(0) + d1.w(1)`` (w the spatial turns) is
compared with the derivative of the constraint's functional discretised independently in the
test (frames at the nodes, the strain of each interval log(R_j^T R_(j+1)) / h, the midpoint
rule), along exp(e [w]) R, extrapolated from two meshes:

* at random frame fields for al = 0 (the rate linear in u: its integration by parts needs only
  R' = R [u]_x, true of every field);
* at an equilibrium of the buckled branch for al = 1/2 (the rate quadratic in u: the parts
  need u' from the balance of moments, true on solutions only).

A density not quadratic in the strains with such a constraint is one line, exit status 2
(tests/test_energy_loading.py).
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

import elastica_auto as ea
from elastica_auto.model.second_variation import as_second_variation
from rod_hessian import expm, logm

MODULE = '''
import numpy as np


def ENERGY():
    import sympy as sp

    from elastica_auto.energy import Energy, Param, Rotation
    s, P, b2, c, mu, T, al = sp.symbols("s P b2 c mu T al", real=True)
    R = Rotation("R")
    x, y, z, tw = (sp.Function(name)(s) for name in ("x", "y", "z", "tw"))
    u1, u2, u3 = R.strain
    return Energy(density=(u1 ** 2 + b2 * u2 ** 2 + c * u3 ** 2) / 2, end1=P * z,
                  s=s, coordinates=[R],
                  quadratures={x: R.d3[0], y: R.d3[1], z: R.d3[2], tw: u3 + al * u1 ** 2},
                  fixed0={R: (1, 0, 0, 0), x: 0, y: 0, z: 0, tw: 0}, fixed1={tw: T},
                  multipliers={tw: mu},
                  parameters={P: Param(0.0), b2: Param(2.0), c: Param(0.8), mu: Param(0.0),
                              T: Param(0.0), al: Param(0.5)})


def exact_start(s, p):
    """The straight column along e_z, untwisted (T = 0, mu = 0)."""
    out = np.zeros((11, len(s)))
    out[0] = 1.0
    out[9] = s
    return out
'''


@pytest.fixture(scope="module")
def twisted(tmp_path_factory):
    path = tmp_path_factory.mktemp("twist") / "twisted_column.py"
    path.write_text(textwrap.dedent(MODULE))
    return ea.load_problem(path)


def _rotation(q):
    w, x, y, z = q / np.linalg.norm(q, axis=0)
    return np.array(((w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)),
                     (2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)),
                     (2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z)))


def _functional(frames, al, w, e):
    """sum_j h (u3 + al u1^2) at the frames exp(e [w_j]) R_j (n + 1, 3, 3)."""
    turned = expm(e * w) @ frames
    n = len(frames) - 1
    u = logm(np.swapaxes(turned[:-1], -1, -2) @ turned[1:]) * n
    return float(np.sum(u[:, 2] + al * u[:, 0] ** 2) / n)


def _compare(problem, state, p, w):
    """The derived linearised constraint applied to the field w, and the derivative of the
    discretised functional along it, extrapolated from n = 200 and 400 (second order)."""
    x, weights = np.polynomial.legendre.leggauss(60)
    gauss, weights = 0.5 * (x + 1), 0.5 * weights
    (con,) = as_second_variation(problem.second_variation(gauss, state(gauss), p),
                                 "d").constraints
    ends = np.array([0.0, 1.0])
    (at_ends,) = as_second_variation(problem.second_variation(ends, state(ends), p),
                                     "d").constraints
    derived = float(weights @ np.sum(np.asarray(con.g) * w(gauss), axis=0)
                    + np.asarray(at_ends.d0) @ w(ends)[:, 0]
                    + np.asarray(at_ends.d1) @ w(ends)[:, 1])
    values = []
    for n in (200, 400):
        s = np.linspace(0, 1, n + 1)
        frames = _rotation(state(s)[:4]).transpose(2, 0, 1)
        ws = w(s).T
        e = 1e-6
        values.append((_functional(frames, p["al"], ws, e)
                       - _functional(frames, p["al"], ws, -e)) / (2 * e))
    return derived, values[1] + (values[1] - values[0]) / 3, abs(values[1] - values[0])


def _field(rng):
    a, b, c = rng.normal(size=(3, 3))

    def w(s):
        s = np.asarray(s, dtype=float)
        return (np.outer(a, np.ones_like(s)) + np.outer(b, s ** 2)
                + np.outer(c, np.sin(3 * s)))
    return w


def test_the_constraint_is_the_derivative_of_its_functional_at_frame_fields(twisted):
    """al = 0: int (u3) ds along exp(e [w]) R, at random frame fields (|q| != 1) and random
    fields w (w(0) != 0: the end part d0 counts too)."""
    rng = np.random.default_rng(8)
    for _ in range(3):
        p = {**twisted.defaults(), "al": 0.0, "mu": rng.uniform(-1, 1),
             "b2": rng.uniform(0.5, 3), "c": rng.uniform(0.3, 2)}
        coef = rng.normal(size=(3, 4))

        def unit(s):
            q = coef[0][:, None] + coef[1][:, None] * s + coef[2][:, None] * s ** 2
            return q / np.sqrt(np.sum(q * q, axis=0))

        def state(s):
            s = np.asarray(s, dtype=float)
            q = unit(s)
            dq = unit(s + 1e-30j).imag / 1e-30
            q0, q1, q2, q3 = q
            d0, d1, d2, d3 = dq
            u = 2 * np.array((q0 * d1 - q1 * d0 - q2 * d3 + q3 * d2,
                              q0 * d2 - q2 * d0 - q3 * d1 + q1 * d3,
                              q0 * d3 - q3 * d0 - q1 * d2 + q2 * d1))
            mb = np.array((u[0], p["b2"] * u[1], p["c"] * u[2] + p["mu"]))   # dL_eff/du
            m = np.einsum("ijm,jm->im", _rotation(q), mb)
            return np.vstack((q * (1 + 0.2 * np.cos(s)), m, np.zeros((4, len(s)))))

        derived, discrete, change = _compare(twisted, state, p, _field(rng))
        assert abs(derived - discrete) <= 0.1 * change + 1e-8 * (1 + abs(derived))


def test_the_constraint_is_the_derivative_of_its_functional_on_a_solution(twisted):
    """al = 1/2 on the column buckled at P = 3 (the branch switched at P_c = pi^2/4, where
    the constraint's multiplier is solved for): the integration by parts uses u' from the
    balance of moments."""
    branches = ea.continuation(twisted, {"P": 0.0}, "P", bounds=(0, 3.0), switch=1)
    ends = [pt for br in branches[1:] for pt in br.points
            if pt.type == "EP" and abs(pt.params["P"] - 3.0) < 1e-9]
    assert ends
    state = ends[0].state
    p = state.params
    assert abs(p["mu"]) > 1e-3                 # the constraint is active: a twisting moment
    y = state(np.linspace(0, 1, 11))
    assert np.max(np.abs(y[4:7])) > 0.1        # buckled
    derived, discrete, change = _compare(twisted, state, p, _field(np.random.default_rng(3)))
    assert abs(derived - discrete) <= 0.1 * change + 1e-7 * (1 + abs(derived))
    assert math.isfinite(derived)
