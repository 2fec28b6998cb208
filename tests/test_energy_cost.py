"""What makes a generated module cheaper (docs/soft-robots.md, "Cost") against what is
independent of it:

* the compiled frame, body moment and quaternion rate (energy/_frames.c) against their
  closed forms: R(q / |q|) = (w^2 - v.v) I + 2 v v^T + 2 w [v]_x for q / |q| = (w, v), R^T m,
  and the Hamilton product q (x) (0, u) / 2 written out, on views with any strides;
* the compiled chain through a frame (`runtime.chain`, energy/_frames.c) against central
  differences of R(q / |q|) and R^T m in q and m, at random quaternions with |q| != 1;
* the Legendre inverse expanded where shorter (`derive._shorter`): the Cosserat rod's x' is
  R v_hat + n / S (the closed form of its constitutive law) and m' = -x' x n at random
  states.
"""

from __future__ import annotations

import inspect

import numpy as np
import sympy as sp

import elastica_auto as ea
from elastica_auto.energy import runtime
from elastica_auto.energy.codegen import _gathered
from elastica_auto.energy.derive import _shorter


def test_the_compiled_frame_body_and_rate_are_their_closed_forms():
    rng = np.random.default_rng(11)
    y = rng.normal(size=(13, 2 * 17))[:, ::2]            # strided rows, as a module's y[3:7]
    q, m = y[3:7], y[7:10]
    R = runtime.frame(q)
    unit = q / np.linalg.norm(q, axis=0)
    w, v = unit[0], unit[1:]
    cross = np.zeros((3, 3, q.shape[1]))
    cross[0, 1], cross[0, 2], cross[1, 2] = -v[2], v[1], -v[0]
    cross[1, 0], cross[2, 0], cross[2, 1] = v[2], -v[1], v[0]
    expected = ((w * w - (v * v).sum(axis=0)) * np.eye(3)[:, :, None]
                + 2 * v[:, None] * v[None, :] + 2 * w * cross)
    assert np.allclose(R, expected, rtol=0, atol=1e-14)
    assert np.allclose(runtime.body(R, m), np.einsum("acp,ap->cp", R, m), rtol=0, atol=1e-14)
    u = rng.normal(size=(3, q.shape[1]))
    a0, a1, a2, a3 = q
    b1, b2, b3 = u[0], u[1], 0.7
    hamilton = 0.5 * np.array([-a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + a2 * b3 - a3 * b2,
                               a0 * b2 + a3 * b1 - a1 * b3, a0 * b3 + a1 * b2 - a2 * b1])
    assert np.allclose(runtime.quaternion_rate(q, u[0], u[1], 0.7), hamilton, rtol=0,
                       atol=1e-14)


def test_the_chain_is_the_derivative_through_the_frame_and_the_body_moment():
    """f = sum F_r : R(q) + F_m . R(q)^T m (F_r, F_m fixed random coefficients, rows_r and
    rows_m overlapping): chain's df/dq and df/dm against central differences."""
    rng = np.random.default_rng(7)
    npts, n = 5, 9
    q = rng.normal(size=(4, npts)) * 1.7
    m = rng.normal(size=(3, npts))
    f_r = rng.normal(size=(3, 3, 3, npts))
    f_m = rng.normal(size=(2, 3, npts))
    rows_r, rows_m, qcols, mcols = [0, 4, 8], [4, 6], [1, 2, 3, 5], [0, 6, 7]

    def f(q, m):
        out = np.zeros((n, npts))
        R = runtime.frame(q)
        out[rows_r] += np.einsum("iabp,abp->ip", f_r, R)
        out[rows_m] += np.einsum("icp,cp->ip", f_m, runtime.body(R, m))
        return out

    jac = rng.normal(size=(n, n, npts))
    expected = jac.copy()
    runtime.chain(jac, runtime.frame(q), q, m, qcols, mcols, rows_r, f_r, rows_m, f_m)
    h = 1e-6
    for j, col in enumerate(qcols):
        dq = np.zeros_like(q)
        dq[j] = h
        expected[:, col] += (f(q + dq, m) - f(q - dq, m)) / (2 * h)
    for a, col in enumerate(mcols):
        dm = np.zeros_like(m)
        dm[a] = h
        expected[:, col] += (f(q, m + dm) - f(q, m - dm)) / (2 * h)
    assert np.allclose(jac, expected, rtol=0, atol=1e-8)
    # the frame's rows alone (no body moment): the same derivatives in those rows
    frame_only = np.zeros((n, n, npts))
    runtime.chain(frame_only, runtime.frame(q), q, m, qcols, mcols, rows_r, f_r, [], None)
    f_m[:] = 0.0
    for j, col in enumerate(qcols):
        dq = np.zeros_like(q)
        dq[j] = h
        assert np.allclose(frame_only[:, col], (f(q + dq, m) - f(q - dq, m)) / (2 * h),
                           rtol=0, atol=1e-8)
    assert not np.any(frame_only[:, mcols])


def test_a_shearable_rod_s_stretch_is_its_closed_form_and_its_strain_cancels():
    """cosserat_rod: x' = R(q) v_hat + n / S at random states (|q| != 1) and parameters;
    the moment balance m' = -x' x n; `derive._shorter` on a quotient whose expansion is
    shorter and on one whose expansion is longer."""
    rod = ea.load_problem("cosserat_rod")
    rng = np.random.default_rng(3)
    y = rng.normal(size=(13, 9))
    p = rod.defaults()
    p.update(S=float(rng.uniform(5, 50)), v1=0.1, v2=-0.2, v3=1.3)
    f = rod.rhs(np.linspace(0, 1, 9), y, p)
    R = runtime.frame(y[3:7])
    v_hat = np.array([p["v1"], p["v2"], p["v3"]])
    assert np.allclose(f[0:3], np.einsum("abk,b->ak", R, v_hat) + y[10:13] / p["S"],
                       rtol=1e-13, atol=1e-13)
    assert np.allclose(f[7:10], -np.cross(f[0:3], y[10:13], axis=0), rtol=1e-12, atol=1e-12)
    a, n = sp.symbols("a n")
    S = sp.Symbol("S", positive=True)
    assert _shorter((S * a + n) / S) == a + n / S
    assert _shorter((a + n) ** 3 / S) == (a + n) ** 3 / S     # its expansion is longer


def test_sums_gathered_by_the_states_where_that_leaves_fewer_operations():
    """`codegen._gathered`: a y + b y and a + b become t = a + b, t y (the sum found once by
    the common subexpressions), the same values; a y + b z, which gathering leaves as it is,
    keeps sympy's own; and the shipped sheared rod's m' is n x (R v_hat) by the three sums
    x' has (its rhs at random states against the closed form, as above, with fewer array
    products than the nine of R v_hat written out per component)."""
    a, b, y, z = sp.symbols("a b y z")
    exprs = [a * y + b * y, a + b]
    temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("t"), order="none")
    t2, r2 = _gathered(exprs, [y], temps, reduced)
    assert sp.count_ops([e for _, e in t2] + list(r2)) < sp.count_ops(
        [e for _, e in temps] + list(reduced))
    values = {a: 0.3, b: -1.7, y: 2.9}
    back = [e.subs(dict(t2)).subs(dict(t2)).subs(values) for e in r2]
    assert [float(v) for v in back] == [float(e.subs(values)) for e in exprs]
    assert any(isinstance(e, sp.Add) and set(e.args) == {a, b} for _, e in t2)
    plain = [a * y + b * z]
    t3, r3 = sp.cse(plain, symbols=sp.numbered_symbols("t"), order="none")
    assert _gathered(plain, [y, z], t3, r3) == (t3, r3)
    source = inspect.getsource(ea.load_problem("cosserat_rod").module.rhs)
    moments = [line for line in source.splitlines() if line.strip().startswith("out[7]")]
    assert moments and moments[0].count("*") == 2, moments
