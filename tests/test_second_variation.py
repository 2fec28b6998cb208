"""The index of vector quadratic forms (elastica_auto.model.second_variation, stability.count_form),
checked against two independent references (tests/form_reference.py) and analytic counts.

The form, for h(s) in R^k on [0, 1]::

    Q[h] = int_0^1 (h'.A h' + 2 h'.C h + h.B h) ds + h(0).E0 h(0) + h(1).E1 h(1),

G0 h(0) = 0, G1 h(1) = 0, optional constraints int g.h ds + d0.h(0) + d1.h(1) = 0. Its index is
the number of negative eigenvalues on the admissible space.

* Analytic counts: k = 1, A = 1, B = -P has the eigenvalues mu = omega^2 - P with omega = n pi
  (n >= 1, fixed-fixed), (n - 1/2) pi (n >= 1, fixed-free and free-fixed) and n pi (n >= 0,
  free-free), so the index is the number of those omega with omega^2 < P. A decoupled (diagonal)
  k = 3 form counts the sum of its scalar parts; a constant orthogonal change of variables
  h = R^T y (A -> R A R^T, ..., G -> G R^T) leaves the count unchanged.
* Random smooth forms (low-degree polynomials and one Fourier mode in s; A = L L^T + 0.5 I,
  B symmetric with entries up to about 40, C of size up to about 3, E0, E1 symmetric) for
  k = 1, 2, 3 and every kind of end condition: count_form must agree with the Morse index
  theorem (conjugate points) and with the dense Legendre-Galerkin count. Cases whose dense
  spectrum has an eigenvalue within NEAR_ZERO of 0 are skipped (justified there) and the
  skips are counted (:func:`test_few_cases_skipped`).
* Integral constraints: count_form against the dense count (conjugate points do not apply).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from elastica_auto.core.errors import ProblemError
from elastica_auto.model.second_variation import Constraint, SecondVariation
from elastica_auto.numerics.stability import count_form
from form_reference import Form, conjugate_count, dense_count, fixed_rows

MESH = np.linspace(0.0, 1.0, 61)

#: A coarse, non-uniform mesh of two elements: the engine must refine it where the coefficients
#: need it (its MAX_PHASE); without refinement P2 on it cannot resolve the oscillating modes.
COARSE = np.array([0.0, 0.3, 1.0])

#: A case is compared only if the dense spectrum has no eigenvalue in (-NEAR_ZERO, NEAR_ZERO),
#: far above every discretisation error of an eigenvalue near zero, measured on these cases:
#: the dense Legendre-Galerkin eigenvalue nearest zero moves by at most 1e-6 from 44 to 70
#: functions per component; RK4 with 2000 steps and 8000 steps finds the same conjugate points
#: (and W U^-1 symmetric to 1e-12); the engine's P2 elements (refined to h w <= 0.2, w the local
#: wavenumber), located by bisection on count_form's shift, are within 4e-5 of the dense
#: eigenvalue nearest zero on MESH and 3e-4 on COARSE. 0.01 is 30 times the largest of these;
#: with eigenvalues spaced by ~pi^2 A it skips only a few per cent of the cases.
NEAR_ZERO = 0.01


def _constant(m):
    m = np.atleast_2d(np.asarray(m, dtype=float))
    return lambda s: np.broadcast_to(m, (len(s), *m.shape)).copy()


def engine_form(form: Form):
    """``evaluate(s) -> SecondVariation`` for the engine, from the reference's callables."""
    e0, e1, g0, g1 = form.ends()

    def evaluate(s):
        a, b, c = form.coefficients(s)
        cons = [Constraint(np.asarray(g(s), dtype=float).T, d1=np.asarray(d1, dtype=float),
                           d0=np.asarray(d0, dtype=float)) for g, d0, d1 in form.constraints]
        return SecondVariation(np.moveaxis(a, 0, -1), np.moveaxis(b, 0, -1),
                               np.moveaxis(c, 0, -1), E0=e0, E1=e1,
                               fixed0=g0 if g0.shape[0] else (),
                               fixed1=g1 if g1.shape[0] else (), constraints=cons)
    return evaluate


def engine_index(form: Form, mesh=MESH) -> int:
    c = count_form(engine_form(form), mesh)
    assert c.index >= 0, c.reason
    return c.index


# ----------------------------------------------------------------------------- analytic


def scalar_count(p, ends):
    """#{omega : omega^2 < p} for A = 1, B = -p; ``ends`` "DD", "DN", "ND" or "NN" (D fixed,
    N natural with E = 0)."""
    n = np.arange(0, 40)
    omega = {"DD": n[1:] * np.pi, "DN": (n[1:] - 0.5) * np.pi, "ND": (n[1:] - 0.5) * np.pi,
             "NN": n * np.pi}[ends]
    return int(np.count_nonzero(omega ** 2 < p))


def scalar_form(p, ends):
    return Form(1, _constant(1.0), _constant(-p), G0=[[1.0]] if ends[0] == "D" else None,
                G1=[[1.0]] if ends[1] == "D" else None)


LOADS = [-3.0, 5.0, 12.0, 30.0, 50.0, 95.0, 150.0]


@pytest.mark.parametrize("ends", ["DD", "DN", "ND", "NN"])
@pytest.mark.parametrize("p", LOADS)
def test_scalar_analytic(p, ends):
    # every load is at least 2 away from a critical omega^2, far above all discretisation errors
    expected = scalar_count(p, ends)
    form = scalar_form(p, ends)
    assert conjugate_count(form).index == expected
    dense, gap, _ = dense_count(form)
    assert dense == expected and gap > 1.0
    assert engine_index(form) == expected
    assert engine_index(form, COARSE) == expected


# three components, different loads and ends: the conjugate points are simple (distinct)
DECOUPLED = [(7.0, "DD"), (40.0, "DN"), (25.0, "NN")]


def decoupled_form(rotation=None):
    """diag(1, 2, 0.5) h'' ... : component i with A_ii = a_i, B_ii = -a_i p_i, so its
    eigenvalues are a_i (omega^2 - p_i), the same signs as the scalar case."""
    a = np.array([1.0, 2.0, 0.5])
    p = np.array([q for q, _ in DECOUPLED])
    g0 = fixed_rows([i for i, (_, e) in enumerate(DECOUPLED) if e[0] == "D"], 3)
    g1 = fixed_rows([i for i, (_, e) in enumerate(DECOUPLED) if e[1] == "D"], 3)
    am, bm = np.diag(a), np.diag(-a * p)
    if rotation is not None:
        am, bm = rotation @ am @ rotation.T, rotation @ bm @ rotation.T
        g0, g1 = g0 @ rotation.T, g1 @ rotation.T
    return Form(3, _constant(am), _constant(bm), G0=g0, G1=g1)


def test_decoupled_is_sum_of_scalar_counts():
    expected = sum(scalar_count(p, e) for p, e in DECOUPLED)
    assert expected == 0 + 2 + 2
    form = decoupled_form()
    assert conjugate_count(form).index == expected
    assert dense_count(form)[0] == expected
    assert engine_index(form) == expected


def test_rotated_decoupled_form():
    # a constant orthogonal R: y = R h turns the form into one with full matrices and G's
    # that are linear combinations of components (given to the engine as matrices)
    rotation, _ = np.linalg.qr(np.random.default_rng(7).normal(size=(3, 3)))
    expected = sum(scalar_count(p, e) for p, e in DECOUPLED)
    form = decoupled_form(rotation)
    assert np.count_nonzero(np.abs(form.A(np.zeros(1))[0]) > 1e-3) == 9
    assert conjugate_count(form).index == expected
    assert dense_count(form)[0] == expected
    assert engine_index(form) == expected


def test_scalar_and_constant_layouts():
    # the same forms through the other layouts of SecondVariation: for k = 1 scalars and (m,)
    # arrays, for k = 3 constant (k, k) matrices and end conditions as component index lists
    for p, ends in ((30.0, "DN"), (50.0, "NN"), (95.0, "DD")):
        def evaluate(s, p=p, ends=ends):
            return SecondVariation(1.0, -p * np.ones(len(s)),
                                   fixed0=[0] if ends[0] == "D" else (),
                                   fixed1=[0] if ends[1] == "D" else ())
        assert count_form(evaluate, MESH).index == scalar_count(p, ends)
    a = np.array([1.0, 2.0, 0.5])
    p = np.array([q for q, _ in DECOUPLED])

    def evaluate(s):
        return SecondVariation(np.diag(a), np.diag(-a * p),
                               fixed0=[i for i, (_, e) in enumerate(DECOUPLED) if e[0] == "D"],
                               fixed1=[i for i, (_, e) in enumerate(DECOUPLED) if e[1] == "D"])
    assert count_form(evaluate, MESH).index == sum(scalar_count(q, e) for q, e in DECOUPLED)


def test_end_terms_robin():
    # k = 1, A = 1, B = 0, E1 = e, h(0) = 0: h = s gives Q = 1 + e, and the eigenproblem
    # -h'' = mu h, h'(1) + e h(1) = 0 has a negative eigenvalue exactly when e < -1;
    # at s = 0 (free, E0 = e, h(1) = 0) likewise. The sign of each end term is checked here.
    for e, expected in ((-0.7, 0), (-1.4, 1), (-3.0, 1)):
        right = Form(1, _constant(1.0), _constant(0.0), E1=[[e]], G0=[[1.0]])
        left = Form(1, _constant(1.0), _constant(0.0), E0=[[e]], G1=[[1.0]])
        for form in (right, left):
            assert conjugate_count(form).index == expected
            assert dense_count(form)[0] == expected
            assert engine_index(form) == expected


# ------------------------------------------------------------------------ random forms


def smooth(rng, shape, size):
    """A random smooth field s -> (m, *shape): a0 + a1 s + a2 s^2 + b cos 2 pi s + c sin 2 pi s,
    the coefficients uniform in [-size, size]."""
    coef = rng.uniform(-size, size, (5, *shape))

    def field(s):
        s = np.asarray(s, dtype=float).reshape(-1, *([1] * len(shape)))
        basis = (np.ones_like(s), s, s * s, np.cos(2 * np.pi * s), np.sin(2 * np.pi * s))
        return sum(b * c for b, c in zip(basis, coef))
    return field


#: End patterns: (G0, G1) builders given (rng, k). "mixed" fixes some components at each end
#: and leaves the others natural; "general*" is a random full-row-rank G (linear combinations).
PATTERNS = {
    "fixed-free": lambda rng, k: (np.eye(k), None),
    "fixed-fixed": lambda rng, k: (np.eye(k), np.eye(k)),
    "free-fixed": lambda rng, k: (None, np.eye(k)),
    "free-free": lambda rng, k: (None, None),
    "mixed": lambda rng, k: (fixed_rows(range(0, k, 2), k), fixed_rows(range(1, k, 2), k)),
    "general0": lambda rng, k: (rng.normal(size=(max(k - 1, 1), k)), fixed_rows([0], k)),
    "general1": lambda rng, k: (None, rng.normal(size=(1, k))),
}
SEEDS = 4
K_VALUES = (1, 2, 3)
CASES = [(k, pattern, i) for k in K_VALUES for pattern in PATTERNS for i in range(SEEDS)]


def random_form(k, pattern, i, constraints=0):
    """A seeded random form (module docstring); -P I in B (P in [-20, 40]) spreads the index
    over 0..8."""
    rng = np.random.default_rng([k, list(PATTERNS).index(pattern), i, constraints])
    lf = smooth(rng, (k, k), 0.5)
    sf = smooth(rng, (k, k), 8.0)
    cf = smooth(rng, (k, k), 1.5)
    p = rng.uniform(-20.0, 40.0)

    def a(s):
        m = lf(s)
        return m @ np.swapaxes(m, 1, 2) + 0.5 * np.eye(k)

    def b(s):
        m = sf(s)
        return 0.5 * (m + np.swapaxes(m, 1, 2)) - p * np.eye(k)

    e0, e1 = rng.normal(size=(2, k, k)) * 2.0
    g0, g1 = PATTERNS[pattern](rng, k)
    cons = [(smooth(rng, (k,), 3.0), rng.normal(size=k), rng.normal(size=k))
            for _ in range(constraints)]
    return Form(k, a, b, cf, 0.5 * (e0 + e0.T), 0.5 * (e1 + e1.T), g0, g1, cons)


@functools.cache
def dense_of(k, pattern, i, constraints=0):
    """The dense count of a random case, computed once for the tests that share it."""
    return dense_count(random_form(k, pattern, i, constraints))


@pytest.mark.parametrize("k,pattern,i", CASES)
def test_random_form(k, pattern, i):
    form = random_form(k, pattern, i)
    dense, gap, _ = dense_of(k, pattern, i)
    if gap < NEAR_ZERO:
        pytest.skip(f"eigenvalue {gap:.2g} within NEAR_ZERO of zero")
    conj = conjugate_count(form)
    assert conj.asymmetry < 1e-6           # W U^-1 symmetric: the Lagrangian plane was kept
    assert conj.index == dense, (conj, dense)
    assert engine_index(form) == dense
    assert engine_index(form, COARSE) == dense


#: Blocks of 4 and 6 components (the Cosserat rod's whole form has 6), whose pivots the
#: compiled count inverts by their eigendecomposition (numerics/_blocks.c): against the dense
#: count (conjugate points are left to the smaller cases, which share the reference).
LARGER = [(k, pattern, i) for k in (4, 6) for pattern in ("fixed-free", "free-free", "mixed",
                                                          "general0") for i in range(2)]


@pytest.mark.parametrize("k,pattern,i", LARGER)
def test_random_form_of_larger_blocks(k, pattern, i):
    form = random_form(k, pattern, i)
    dense, gap, _ = dense_of(k, pattern, i)
    if gap < NEAR_ZERO:
        pytest.skip(f"eigenvalue {gap:.2g} within NEAR_ZERO of zero")
    assert engine_index(form) == dense
    assert engine_index(form, COARSE) == dense


def test_larger_blocks_are_not_all_stable():
    counts = [dense_of(*c) for c in LARGER]
    assert sum(gap < NEAR_ZERO for _, gap, _ in counts) <= 2
    assert len({index for index, _, _ in counts}) >= 4


CONSTRAINED = [(k, pattern, i, r) for k in K_VALUES for r in (1, 2)
               for pattern in ("fixed-free", "free-free", "mixed", "general1") for i in range(2)]


@pytest.mark.parametrize("k,pattern,i,r", CONSTRAINED)
def test_random_constrained_form(k, pattern, i, r):
    form = random_form(k, pattern, i, constraints=r)
    dense, gap, _ = dense_of(k, pattern, i, r)
    if gap < NEAR_ZERO:
        pytest.skip(f"eigenvalue {gap:.2g} within NEAR_ZERO of zero")
    free = dense_count(Form(**{**form.__dict__, "constraints": []}))[0]
    # a constraint removes at most one negative direction: n_- drops by at most r (interlacing)
    assert free - r <= dense <= free
    assert engine_index(form) == dense
    assert engine_index(form, COARSE) == dense


def test_few_cases_skipped():
    # the skip rule is a property of the reference alone, so it is counted here again
    skipped = sum(dense_of(*c)[1] < NEAR_ZERO for c in CASES)
    skipped_c = sum(dense_of(*c)[1] < NEAR_ZERO for c in CONSTRAINED)
    assert skipped <= 0.1 * len(CASES) and skipped_c <= 0.1 * len(CONSTRAINED)


def test_indices_spread():
    # the random cases are not all trivially stable: they cover indices 0..5 at least
    counts = {dense_of(*c)[0] for c in CASES}
    assert set(range(6)) <= counts


def test_end_constraint_equals_essential_condition():
    # int 0 + d1.h(1) = 0 with d1 = e_0 is the essential condition h_0(1) = 0: the engine's
    # bordered count (constraints) against its restriction (fixed1), and the dense count
    for k in (1, 2, 3):
        form = random_form(k, "fixed-free", 3)
        as_constraint = Form(**{**form.__dict__,
                                "constraints": [(lambda s, k=k: np.zeros((len(s), k)),
                                                 np.zeros(k), np.eye(k)[0])]})
        as_fixed = Form(**{**form.__dict__, "G1": fixed_rows([0], k)})
        dense, gap, _ = dense_count(as_fixed)
        assert gap > NEAR_ZERO
        assert dense_count(as_constraint)[0] == dense == conjugate_count(as_fixed).index
        assert engine_index(as_constraint) == dense == engine_index(as_fixed)


def test_shifted_counts_follow_the_dense_spectrum():
    # count_form(shift=mu) counts the eigenvalues below mu: check it between the dense
    # eigenvalues, so more of the spectrum than its sign is compared
    form = random_form(2, "mixed", 1)
    mu = dense_count(form)[2]
    evaluate = engine_form(form)
    for lo, hi in zip(mu[:8], mu[1:9]):
        if hi - lo > 2 * NEAR_ZERO:
            mid = 0.5 * (lo + hi)
            assert count_form(evaluate, MESH, shift=mid).index == np.count_nonzero(mu < mid)


# ----------------------------------------------------------------------- parts


def direct_sum(forms, parts, coupling=0.0, tie=False, mix=False):
    """``evaluate(s)`` for the engine: the direct sum of the reference ``forms`` (each a
    `Form`), form j on the components ``parts[name_j]`` of h in R^k (interleaved), with
    ``parts`` declared. ``coupling``: that multiple of a fixed matrix couples the parts in C;
    ``tie``: one more constraint, int h_first + h_last ds = 0, across the first two parts;
    ``mix``: G0's rows made orthonormal and then rotated into each other (the same fixed
    directions, every row of G0 across both parts)."""
    comps = list(parts.values())
    k = sum(len(c) for c in comps)

    def embed(rows, values, width):            # rows of a (r, k_j) block into (r, k)
        out = np.zeros((values.shape[0], width))
        out[:, rows] = values
        return out

    def evaluate(s):
        m = len(s)
        a, b, c = (np.zeros((m, k, k)) for _ in range(3))
        e0, e1 = np.zeros((k, k)), np.zeros((k, k))
        g0, g1, cons = [], [], []
        for form, rows in zip(forms, comps):
            ix = np.ix_(range(m), rows, rows)
            a[ix], b[ix], c[ix] = form.coefficients(s)
            f0, f1, h0, h1 = form.ends()
            e0[np.ix_(rows, rows)], e1[np.ix_(rows, rows)] = f0, f1
            g0.append(embed(rows, h0, k))
            g1.append(embed(rows, h1, k))
            for g, d0, d1 in form.constraints:
                field = np.zeros((k, m))
                field[rows] = np.asarray(g(s), dtype=float).reshape(m, -1).T
                cons.append(Constraint(field, d1=embed(rows, np.atleast_2d(d1), k)[0],
                                       d0=embed(rows, np.atleast_2d(d0), k)[0]))
        c += coupling * np.ones((k, k))
        if tie:
            g = np.zeros((k, m))
            g[comps[0][0]] = g[comps[1][-1]] = 1.0
            cons.append(Constraint(g))
        g0, g1 = np.vstack(g0), np.vstack(g1)
        if mix:
            g0 = np.linalg.qr(g0.T)[0].T
            g0 = np.linalg.qr(np.random.default_rng(3).normal(size=(len(g0),) * 2))[0] @ g0
        return SecondVariation(np.moveaxis(a, 0, -1), np.moveaxis(b, 0, -1),
                               np.moveaxis(c, 0, -1), E0=e0, E1=e1,
                               fixed0=g0 if len(g0) else (), fixed1=g1 if len(g1) else (),
                               constraints=cons, parts=parts)
    return evaluate


#: Random cases (k, pattern, seed, constraints) summed: a general G at s = 0 and a constraint
#: in the first, component selections in the second; their dense spectra keep NEAR_ZERO
#: away from zero (asserted).
SUMMANDS = [(2, "general0", 2, 1), (1, "mixed", 1, 0)]


def summands():
    forms = [random_form(*c) for c in SUMMANDS]
    dense = [dense_of(*c) for c in SUMMANDS]
    assert all(gap > NEAR_ZERO for _, gap, _ in dense)
    return forms, [d[0] for d in dense]


@pytest.mark.parametrize("mix", [False, True])
@pytest.mark.parametrize("parts", [{"out": [0, 2], "in": [1]}, {"out": [1, 2], "in": [0]}])
def test_parts_of_a_direct_sum_are_the_summands_counts(parts, mix):
    # the direct sum of two random forms, interleaved: each part's count is its summand's
    # dense count, the index their sum, and the same as the whole form's (parts not declared)
    forms, expected = summands()
    evaluate = direct_sum(forms, parts, mix=mix)
    if mix:
        assert np.min(np.abs(evaluate(MESH).fixed0)) > 1e-3      # each row across the parts
    got = count_form(evaluate, MESH)
    assert got.parts == dict(zip(parts, expected)) and got.index == sum(expected) > 0
    whole = count_form(lambda s: _without_parts(evaluate(s)), MESH)
    assert whole.index == got.index and whole.parts == {}
    assert count_form(evaluate, COARSE).parts == got.parts


def _without_parts(form):
    form.parts = {}
    return form


@pytest.mark.parametrize("how", ["coupling", "tie"])
def test_parts_of_a_coupled_form_are_not_counted(how):
    # a coefficient or a constraint that couples the parts: no part has an index of its own
    # (-1 each), and the index is the whole form's, here the dense count of the same form
    forms, expected = summands()
    parts = {"out": [0, 2], "in": [1]}
    evaluate = direct_sum(forms, parts, coupling=1e-6 if how == "coupling" else 0.0,
                          tie=how == "tie")
    got = count_form(evaluate, MESH)
    assert got.parts == {"out": -1, "in": -1}
    if how == "coupling":      # 1e-6 moves no eigenvalue across zero (gaps above NEAR_ZERO)
        assert got.index == sum(expected)
    else:                      # one more constraint: the interlacing bound
        assert sum(expected) - 1 <= got.index <= sum(expected)
    assert got.index == count_form(lambda s: _without_parts(evaluate(s)), MESH).index


@pytest.mark.parametrize("parts,match", [
    ({"a": [0, 1], "b": [1, 2]}, "do not partition"),
    ({"a": [0, 1]}, "do not partition"),
    ({"a": [0, 1], "b": []}, "non-empty list"),
    ({"a": [0, 1], "b": [2.0]}, "non-empty list"),
    ([[0], [1, 2]], "must be a dict"),
])
def test_parts_are_validated(parts, match):
    with pytest.raises(ProblemError, match=match):
        SecondVariation(np.eye(3), np.zeros((3, 3)), parts=parts)


# ------------------------------------------------------------------------------ errors


def test_legendre_condition_failure():
    # A has a negative eigenvalue near s = 0.7: the index is not defined
    def a(s):
        m = np.tile(np.eye(2), (len(s), 1, 1))
        m[:, 1, 1] = 1.0 - 3.0 * np.exp(-((s - 0.7) / 0.05) ** 2)
        return m
    form = Form(2, a, _constant(-5.0 * np.eye(2)), G0=np.eye(2))
    with pytest.raises(ProblemError, match="positive definite") as err:
        count_form(engine_form(form), MESH)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("field", ["A", "B"])
def test_a_field_is_refused_where_it_is_not_symmetric_and_accepted_to_rounding(field):
    # exactly symmetric (a derived module's fields): accepted by one comparison; a rounding
    # error's asymmetry (1e-14 relative): accepted; 1e-6 at one point: refused, naming the
    # entry and the point
    m = 201
    rng = np.random.default_rng(7)
    x = rng.normal(size=(3, 3, m))
    sym = x + x.transpose(1, 0, 2) + 6 * np.eye(3)[:, :, None]
    other = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, m))
    for value in (sym, sym + 1e-14 * rng.normal(size=sym.shape)):
        SecondVariation(**{field: value, "AB".replace(field, ""): other})
    bad = sym.copy()
    bad[0, 2, 17] += 1e-6
    with pytest.raises(ProblemError, match=rf"{field} is not symmetric: {field}\[0, 2\] - "
                                           rf"{field}\[2, 0\] = 1e-06 at point 17"):
        SecondVariation(**{field: bad, "AB".replace(field, ""): other})
