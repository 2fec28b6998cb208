"""The stability index (docs/design.md, "Stability index"),
checked against facts the program does not compute:

* the critical loads of the straight rod (paper 3.2), found here by Brent's method on the
  characteristic equation, and the index they imply (derived below, including P < 0);
* an independent count of negative eigenvalues of the second variation: a Legendre-Galerkin
  discretisation of the quadratic form, solved as a dense symmetric eigenproblem
  (:class:`DenseSecondVariation`; the engine uses a Jacobi field and P1 finite elements);
* exact symmetries (mirror images, psi -> pi - psi with eps -> -eps), the paper's statements
  (sections 3.2, 4.1.1) and an independent shooting solve (tests/shooting.py).

The energy of the elastica with the lever arm, after eliminating the positions (module
docstring of equations/elastica_lever_arm.py, derived again here from the load's potential
-F . (r(1) + eps d_arm), F = P (sin alpha, -cos alpha), d_arm at angle theta(1) - psi)::

    E[theta] = int_0^1 (theta'^2/2 + P cos(theta - alpha)) ds + eps P cos(psi + alpha - theta(1)),

so, for variations h with h(0) = 0 (the clamp), the second variation is

    Q[h] = int_0^1 (h'^2 - P cos(theta - alpha) h^2) ds - eps P cos(psi + alpha - theta(1)) h(1)^2.

The index is the number of negative eigenvalues of Q (with respect to the L2 inner product).
"""

from __future__ import annotations

import csv
import math
import re
from collections import defaultdict

import numpy as np
import pytest
from numpy.polynomial import legendre
from scipy.interpolate import CubicHermiteSpline
from scipy.linalg import cholesky, solve_triangular
from scipy.optimize import brentq

import jacobi
import shooting
from elastica_auto.execution import runfile
from elastica_auto.numerics import stability
from elastica_auto.core.solution import State
from helpers import elastica_run_file, run_cli, run_plan

TWO_PI = 2 * math.pi
P1 = math.pi ** 2 / 4          # the paper's loads: first and second buckling loads of eps = 0
P2 = 9 * math.pi ** 2 / 4

#: Cases whose smallest |eigenvalue| of Q is below this are not compared: the count there is
#: decided by discretisation error. The engine's P1 elements on 800 elements (h = 1/800) shift
#: an eigenvalue mu by about h^2/12 int h''^2 <= h^2/12 (|b|max + |mu|)^2 <= 2e-4 for |P| <= 40,
#: and the profiles interpolated from the 101-point grid below are good to ~1e-7 in theta
#: (cubic Hermite with exact slopes kappa: h^4/384 max|theta''''| <= 1e-8/384 * 3000), so
#: 0.05 is more than a hundred times every error that could flip a count. The dense count's
#: own error (48 integrated Legendre polynomials, 128 Gauss points) is below 1e-9 (first test).
MU_MIN = 0.05


# ---- an independent discretisation of the second variation ---------------------------------

class DenseSecondVariation:
    """Q[h] = int_0^1 (h'^2 + b h^2) ds + c h(1)^2 on {h : h(0) = 0} by Legendre-Galerkin.

    Basis: phi_1 = s and phi_j(s) = int_0^s L_{j-1}(2t - 1) dt (j >= 2), i.e.
    (L_j(x) - L_{j-2}(x)) / (2 (2j - 1)) with x = 2s - 1: phi_j' = L_{j-1}(x), phi_j(0) = 0,
    and phi_j(1) = 0 except phi_1(1) = 1. Stiffness K and mass M by Gauss-Legendre quadrature;
    the eigenvalues of Q are those of the symmetric-definite pencil (K, M), computed as the
    eigenvalues of R^-T K R^-1 with M = R^T R. (Plain loops and einsum rather than matrix
    products: multithreaded BLAS on these small matrices is slow on a busy machine.)
    """

    def __init__(self, size: int = 48, nodes: int = 128):
        x, w = legendre.leggauss(nodes)
        self.s, self.w = (x + 1) / 2, w / 2
        lv = np.empty((size + 1, nodes))
        lv[0], lv[1] = 1.0, x
        for n in range(1, size):
            lv[n + 1] = ((2 * n + 1) * x * lv[n] - n * lv[n - 1]) / (n + 1)
        phi, dphi = np.empty((size, nodes)), np.empty((size, nodes))
        phi[0], dphi[0] = self.s, 1.0
        for j in range(1, size):
            phi[j] = (lv[j + 1] - lv[j - 1]) / (2 * (2 * j + 1))
            dphi[j] = lv[j]
        r = cholesky((phi * self.w) @ phi.T)                   # M = R^T R
        r_inv = solve_triangular(r, np.eye(size))
        self.phi = r_inv.T @ phi                               # R^-T phi
        self.stiff = r_inv.T @ ((dphi * self.w) @ dphi.T) @ r_inv
        self.end = r_inv.T[:, 0]                               # R^-T phi(1)

    def eigenvalues(self, b, c):
        """Eigenvalues for b given on ``self.s`` (array or callable) and the end coefficient c."""
        b = b(self.s) if callable(b) else np.broadcast_to(np.asarray(b, dtype=float), self.s.shape)
        k = (self.stiff + np.einsum("ik,k,jk->ij", self.phi, self.w * b, self.phi)
             + c * np.outer(self.end, self.end))
        return np.linalg.eigvalsh(k)


DENSE = DenseSecondVariation()


def elastica_form(theta, theta1, p):
    """(b, c) of Q for the elastica (module docstring): theta a callable, theta1 = theta(1)."""
    def b(s):
        return -p["P"] * np.cos(theta(s) - p["alpha"])
    c = -p["eps"] * p["P"] * math.cos(p["psi"] + p["alpha"] - theta1)
    return b, c


def dense_count(theta, theta1, p):
    """(number of negative eigenvalues, smallest |eigenvalue|) of Q at the profile theta."""
    mu = DENSE.eigenvalues(*elastica_form(theta, theta1, p))
    return int(np.sum(mu < 0)), float(np.min(np.abs(mu)))


def profile_theta(grid, profile):
    """theta on [0, 1] from a stored profile [theta, kappa, x, y] on ``grid``: cubic Hermite
    with the exact slopes theta' = kappa."""
    return CubicHermiteSpline(grid, profile[0], profile[1])


def profile_count(grid, profile, p):
    return dense_count(profile_theta(grid, profile), float(profile[0, -1]), p)


def params_at(columns, names, i):
    return {k: float(columns[k][i]) for k in names}


# ---- the critical loads of the straight rod (paper 3.2) ------------------------------------

def positive_critical_loads(eps, p_max):
    """Roots P in (0, p_max] of sqrt(P) cos sqrt(P) - P eps sin sqrt(P) = 0, sqrt(P) != n pi.

    With q = sqrt(P) > 0 this is g(q) = cos q - eps q sin q = 0 (the factor q dropped). On each
    interval [n pi, (n + 1) pi], g = sin q (cot q - eps q) inside, and cot q - eps q has
    derivative -1/sin^2 q - eps < 0 for |eps| <= 1: exactly one root per interval, and
    g(n pi) = (-1)^n, g((n + 1) pi) = (-1)^(n + 1) bracket it (q = n pi itself is never one)."""
    assert abs(eps) <= 1

    def g(q):
        return math.cos(q) - eps * q * math.sin(q)

    out, n = [], 0
    while n * math.pi < math.sqrt(p_max):
        q = brentq(g, n * math.pi, (n + 1) * math.pi, xtol=1e-15, rtol=1e-15)
        if q * q <= p_max:
            out.append(q * q)
        n += 1
    return out


def negative_critical_load(eps):
    """The zero eigenvalue of the straight rod at P = -k^2 < 0: h = sinh(k s) and the end
    condition h'(1) + c h(1) = 0, c = -eps P = eps k^2, give cosh k + eps k sinh k = 0 (the
    characteristic equation continued to imaginary sqrt(P)), i.e. k tanh k = -1/eps. k tanh k
    increases from 0 to infinity: exactly one root for eps < 0, none for eps >= 0."""
    if eps >= 0:
        return None
    k = brentq(lambda k: k * math.tanh(k) + 1 / eps, 1e-12, 5 - 1 / eps, xtol=1e-15)
    return -k * k


def trivial_index(P, eps):
    """Index of the straight rod (psi = 0, theta = alpha = theta0): b = -P, c = -eps P.

    P >= 0: the number of critical loads below P (paper 3.2; at P = 0, Q = int h'^2 > 0; each
    critical load is a simple zero eigenvalue crossing). For eps < 0, where Q is not monotone
    in P, this is the paper's claim; test 1 confirms it with the dense count.
    P < 0: b = |P| > 0 and c = eps |P|. For eps >= 0, Q > 0: index 0. For eps < 0 the only
    negative term is the rank-one -|eps P| h(1)^2, so the index is at most 1. It is 0 near
    P = 0 (h(1)^2 <= int h'^2 for h(0) = 0, so Q >= (1 - |eps P|) int h'^2 > 0), it can only
    change where Q has a zero eigenvalue, i.e. at the negative critical load, and it is 1 for
    large |P|: h = sinh(k s)/sinh k, k = sqrt|P|, gives int h'^2 + k^2 h^2 = h h'(1) = k coth k
    and Q[h] = k coth k - |eps| k^2 < 0 once |eps| k > coth k. Hence index 1 iff P < P_neg."""
    if P >= 0:
        return sum(1 for pc in positive_critical_loads(eps, P) if pc < P)
    neg = negative_critical_load(eps)
    return int(neg is not None and P < neg)


def critical_distance(P, eps):
    loads = positive_critical_loads(eps, max(P, 0.0) + 50.0)
    neg = negative_critical_load(eps)
    return min(abs(P - pc) for pc in loads + ([neg] if neg is not None else []))


# ---- 0. the reference itself --------------------------------------------------------------

def test_dense_count_reproduces_the_exact_spectra_of_the_straight_rod():
    """For b = -P constant the eigenfunctions are sin(w s) (w^2 = mu + P > 0) or sinh(k s) and
    the eigenvalues roots of w cos w + c sin w = 0 (resp. k cosh k + c sinh k = 0). With c = 0
    they are ((j - 1/2) pi)^2 - P exactly."""
    mu = DENSE.eigenvalues(0.0, 0.0)[:8]
    exact = [((j - 0.5) * math.pi) ** 2 for j in range(1, 9)]
    # rounding: cond(M) ~ 4e7 for this basis, so ~1e-9 relative at worst
    np.testing.assert_allclose(mu, exact, rtol=1e-9)
    for P, c in ((30.0, -15.0), (-5.0, 2.5), (12.0, 6.0), (40.0, -40.0)):
        mu = DENSE.eigenvalues(-P, c)
        for m in mu[:5]:
            lam = m + P
            if lam > 0:
                w = math.sqrt(lam)
                resid = (w * math.cos(w) + c * math.sin(w)) / (1 + w + abs(c))
            else:
                k = math.sqrt(-lam)
                resid = (k * math.cosh(k) + c * math.sinh(k)) / ((1 + k + abs(c)) * math.cosh(k))
            assert abs(resid) < 1e-9, (P, c, m, resid)


# ---- 1. the straight rod: direct counts against the critical loads --------------------------

@pytest.mark.parametrize("eps", [0.25, 0.5, -0.25, -0.5])
def test_trivial_index_equals_the_number_of_critical_loads_below_P(elastica, eps):
    # The paper's brackets for the k-th critical load (3.2), and one negative load for eps < 0.
    pos = positive_critical_loads(eps, 100.0)
    for k, pc in enumerate(pos, 1):
        if eps > 0:
            assert (k - 1) ** 2 * math.pi ** 2 < pc < (2 * k - 1) ** 2 * math.pi ** 2 / 4
        else:
            assert (2 * k - 1) ** 2 * math.pi ** 2 / 4 < pc < k ** 2 * math.pi ** 2
    assert (negative_critical_load(eps) is None) == (eps > 0)

    s = np.linspace(0.0, 1.0, 21)
    # a grid, and both sides of every critical load in range (the count must jump there)
    loads = positive_critical_loads(eps, 60.0) + [negative_critical_load(eps) or -100.0]
    near = [pc + d for pc in loads for d in (-0.02, 0.02) if -30.0 <= pc <= 60.0]
    assert len(near) >= (6 if eps < 0 else 4)
    checked = 0
    for P in list(np.linspace(-30.0, 60.0, 61)) + near:
        P = float(P)
        # theta0 = alpha = angle: the same rod rotated with its load (b, c unchanged);
        # psi = pi turns the arm back: c = +eps P, the straight rod of -eps.
        for psi, angle, e in ((0.0, 0.0, eps), (0.0, 0.7, eps), (math.pi, 0.0, -eps)):
            # The engine's P1 elements shift the eigenvalue of sin(w s) by ~ w^4 h^2 / 12
            # <= 5e-4 (w^2 ~ P <= 60, h = 1/800), and d mu / d P = O(1): 1e-2 away from a
            # critical load |mu| is well above that.
            if critical_distance(P, e) < 1e-2:
                continue
            expected = trivial_index(P, e)
            p = {**elastica.defaults(), "P": P, "eps": eps, "psi": psi, "alpha": angle,
                 "theta0": angle}
            y = elastica.exact_start(s, p)
            state = State.from_values(elastica, s, y, p)
            assert stability.index(elastica, state) == expected, (P, psi, angle)
            assert jacobi.direct_index(elastica, state) == (expected, expected), (P, psi, angle)
            # the analysis of trivial_index, checked by the dense count (accurate to 1e-9)
            count, mu_min = dense_count(lambda x: 0 * x, 0.0, {**p, "eps": e, "psi": 0.0,
                                                               "alpha": 0.0})
            assert mu_min > 1e-6 and count == expected, (P, e, count, expected)
            checked += 1
    assert checked >= 3 * 55
    # negative P: index 1 below the negative critical load exactly when eps < 0
    assert trivial_index(-30.0, eps) == (1 if eps < 0 else 0)


# ---- 2. random states: Jacobi field = finite elements = dense count ------------------------

def _random_states(elastica, n, seed=20240611):
    """Smooth profiles theta(s) = t0 + sum_k a_k cos(k pi s) + b_k sin(k pi s), k <= 4, with
    random P in [-40, 40], eps in [-1, 1], psi, alpha in [0, 2 pi). Not equilibria: Q is a
    quadratic form for any theta."""
    rng = np.random.default_rng(seed)
    mesh = np.linspace(0.0, 1.0, 201)
    k = np.arange(1, 5)[:, None]
    for _ in range(n):
        t0 = rng.uniform(-math.pi, math.pi)
        a, b = rng.normal(0, 1.0, 4) / k[:, 0], rng.normal(0, 1.0, 4) / k[:, 0]

        def theta(s, a=a, b=b, t0=t0):
            s = np.asarray(s, dtype=float)
            return t0 + a @ np.cos(k * math.pi * s[None]) + b @ np.sin(k * math.pi * s[None])

        def dtheta(s, a=a, b=b):
            s = np.asarray(s, dtype=float)
            return (k[:, 0] * math.pi * (-a)) @ np.sin(k * math.pi * s[None]) + \
                (k[:, 0] * math.pi * b) @ np.cos(k * math.pi * s[None])

        p = {**elastica.defaults(), "P": rng.uniform(-40, 40), "eps": rng.uniform(-1, 1),
             "psi": rng.uniform(0, TWO_PI), "alpha": rng.uniform(0, TWO_PI), "theta0": t0}
        y = np.vstack((theta(mesh), dtheta(mesh), np.zeros_like(mesh), np.zeros_like(mesh)))
        yield theta, p, State.from_values(elastica, mesh, y, p)


def test_direct_counts_agree_with_a_dense_eigenvalue_count_on_random_states(elastica):
    n, compared, wrong_sign = 200, 0, 0
    indices = []
    for theta, p, state in _random_states(elastica, n):
        th1 = float(theta(np.array([1.0]))[0])
        # the module's coefficients are the second variation of the energy (module docstring)
        s = np.linspace(0.0, 1.0, 11)
        a, b, c = jacobi.scalar_form(elastica.second_variation(s, state(s), p))
        want_b, want_c = elastica_form(theta, th1, p)
        np.testing.assert_allclose(np.broadcast_to(a, s.shape), 1.0, rtol=0, atol=0)
        # the state interpolates theta (cubic Hermite, exact slopes, h = 1/200) to within
        # h^4/384 max|theta^(4)| <= 1.6e-12 * (4 pi)^4 * 1.5 < 1e-7
        np.testing.assert_allclose(b, want_b(s), rtol=0, atol=1e-6 * abs(p["P"]))
        assert c == pytest.approx(want_c, rel=0, abs=1e-9 * (1 + abs(p["P"])))

        mu = DENSE.eigenvalues(want_b, want_c)
        if np.min(np.abs(mu)) < MU_MIN:
            continue
        compared += 1
        expected = int(np.sum(mu < 0))
        engine = stability.index(elastica, state)
        field, fem = jacobi.direct_index(elastica, state)
        assert engine == field == fem == expected, (p, engine, field, fem, expected, mu[:4])
        indices.append(expected)
        # teeth: the end term with the wrong sign (natural condition h'(1) = -c h(1))
        flipped = DENSE.eigenvalues(want_b, -want_c)
        wrong_sign += int(np.sum(flipped < 0)) != expected
    assert compared >= 0.9 * n, compared
    # the sample is not degenerate: indices 0, 1 and 2 each occur several times
    counts = np.bincount(indices)
    assert len(counts) >= 3 and np.all(counts[:3] >= 5), counts
    print(f"indices {counts}, wrong sign of c changes the count on {wrong_sign}/{compared}")
    # docs/design.md ("Second variation and the natural end condition"): the wrong sign of c
    # changes the count on about half of random states
    assert wrong_sign >= 0.25 * compared, (wrong_sign, compared)


# ---- 3. the fold rule against the direct count on rotating_arm ------------------------------

def _transition(text):
    m = re.fullmatch(r"(-?\d+) -> (-?\d+)", text)
    assert m, text
    return int(m.group(1)), int(m.group(2))


def test_rule_and_direct_count_agree_along_rotating_arm(rotating_arm):
    branches = rotating_arm.result.branches
    assert len(branches) == 8
    nfolds = 0
    for br in branches:
        assert br.disagreements == []
        assert not br.singular_start
        for k, p in enumerate(br.points):
            assert "index disagreement" not in p.note, p.note
            if p.type in ("LP", "BP"):
                continue
            assert p.index == p.index_rule == p.index_direct >= 0, (k, p.type, p.note)
        for p in br.folds:
            before, after = _transition(br.transition(p))
            assert abs(before - after) == 1, br.transition(p)
            nfolds += 1
    assert nfolds >= 40


def test_first_index_of_each_psi_branch_is_the_critical_load_count(rotating_arm):
    """The straight rod at P = pi^2/4 and 9 pi^2/4 has index 1 and 2 for eps = 0.25 and 0.5
    (paper 3.2: P^+_cr,1 < pi^2/4 < P^+_cr,2 < 9 pi^2/4 < P^+_cr,3)."""
    seen = set()
    for br in rotating_arm.result.branches:
        p0 = br.points[0]
        eps, P = p0.params["eps"], p0.params["P"]
        assert p0.params["psi"] == 0.0 and p0.ordinates["m0"] == 0.0
        expected = trivial_index(P, eps)
        paper = {P1: 1, P2: 2}[min((P1, P2), key=lambda v: abs(v - P))]
        assert expected == paper
        assert p0.index == p0.index_direct == expected
        seen.add((eps, round(P, 6)))
    assert len(seen) == 4


def _by_pair(branches):
    out = defaultdict(list)
    for br in branches:
        p0 = br.points[0].params
        out[(p0["eps"], min((P1, P2), key=lambda v: abs(v - p0["P"])))].append(br)
    return out


def test_paper_statements_on_the_index_of_psi_branches(rotating_arm):
    """Paper 4.1.1: for eps = 0.25 the P = pi^2/4 family reaches index 0 and the P = 9 pi^2/4
    family has indices one and two only; for eps = 0.5, P = 9 pi^2/4 an index-0 family exists."""
    pairs = _by_pair(rotating_arm.result.branches)
    indices = {key: {p.index for br in brs for p in br.points} for key, brs in pairs.items()}
    assert 0 in indices[(0.25, P1)] and indices[(0.25, P1)] <= {0, 1}
    assert indices[(0.25, P2)] == {1, 2}
    assert 0 in indices[(0.5, P2)]


def test_straight_rods_met_by_psi_branches_have_the_critical_load_index(rotating_arm):
    """m0 = theta'(0) = 0 with theta(0) = alpha = 0 makes theta = 0 (uniqueness for the IVP),
    and then the free end needs eps P sin psi = 0: every zero of m0 on a psi-branch is a
    straight rod at psi = 0 or pi (mod 2 pi). At psi = pi, c = +eps P: the straight rod of
    -eps, whose index is 0 below P^-_cr,1 (paper 4.1.1), here the critical-load count of -eps.
    The index is constant between folds, so the points either side of the zero carry it."""
    found = defaultdict(int)
    for br in rotating_arm.result.branches:
        pts = br.points
        eps, P = pts[0].params["eps"], pts[0].params["P"]
        for i in range(len(pts) - 1):
            a, b = pts[i], pts[i + 1]
            m_a, m_b = a.ordinates["m0"], b.ordinates["m0"]
            if abs(m_a) < 1e-9:        # a point on the straight rod itself (a UZ at 2 pi k)
                r = math.remainder(a.params["psi"], math.pi)
                assert abs(r) < 1e-9
                turns = round(a.params["psi"] / math.pi)
                if a.type not in ("LP", "BP"):
                    want = trivial_index(P, eps if turns % 2 == 0 else -eps)
                    assert a.index == want, (a.params, a.index, want)
                    found[turns % 2] += 1
                continue
            if m_a * m_b >= 0 or abs(m_b) < 1e-9:
                continue
            # a zero of m0 strictly between two points: a multiple of pi lies between them
            lo, hi = sorted((a.params["psi"], b.params["psi"]))
            turns = [n for n in range(math.ceil(lo / math.pi), math.floor(hi / math.pi) + 1)]
            assert len(turns) == 1, (lo, hi)
            want = trivial_index(P, eps if turns[0] % 2 == 0 else -eps)
            for q in (a, b):
                if q.type not in ("LP", "BP"):
                    assert q.index == want, (eps, P, q.params["psi"], q.index, want)
            found[turns[0] % 2] += 1
    # the straight rod at psi = pi (odd multiples) is met on every (eps, P)
    print("straight rods met (psi = 0, pi mod 2 pi):", found[0], found[1])
    assert found[1] >= 8 and found[0] >= 8, dict(found)


def test_index_of_every_stored_point_matches_the_dense_count(rotating_arm):
    """The index column of every point of the file (profiles on the 101-point grid) against the
    dense count, wherever the smallest |eigenvalue| exceeds MU_MIN."""
    bf = rotating_arm.file
    grid = bf.profile_grid
    total = skipped = 0
    for b in bf.branches:
        c = b.columns
        for i in range(len(b)):
            if c["type"][i] in ("LP", "BP"):
                continue
            total += 1
            count, mu_min = profile_count(grid, b.profiles[i], params_at(c, bf.parameters, i))
            if mu_min < MU_MIN:
                skipped += 1
                continue
            assert c["index"][i] == count, (b.number, i, c["index"][i], count)
    assert total > 1000 and skipped < 0.1 * total, (total, skipped)


# ---- 4. trivial_buckling: branch points at the critical loads, supercritical pitchforks -----

def _trivial_and_switched(run):
    trivial = [br for br in run.result.branches if br.start == "trivial"]
    switched = defaultdict(dict)
    for br in run.result.branches:
        m = re.fullmatch(r"switch at (BP\d+)", br.start)
        if m:
            switched[m.group(1)][br.direction] = br
    return trivial, switched


def test_branch_points_of_the_straight_rod_are_the_critical_loads(trivial_buckling):
    plan = trivial_buckling.plan
    lower, upper = plan.stops.lower, plan.stops.upper
    trivial, _ = _trivial_and_switched(trivial_buckling)
    assert sorted(br.points[0].params["eps"] for br in trivial) == [-0.5, -0.25, 0.25, 0.5]
    for br in trivial:
        eps = br.points[0].params["eps"]
        assert br.points[0].params["P"] == 0.0 and br.direction == 1
        # every critical load the branch passes: the positive ones below the upper bound (the
        # negative one of eps < 0 lies below the lower bound, which the branch never visits)
        expected = [pc for pc in positive_critical_loads(eps, upper) if pc < upper]
        neg = negative_critical_load(eps)
        assert neg is None or neg < lower
        bps = [p for p in br.points if p.type == "BP"]
        got = [p.params["P"] for p in bps]
        assert len(got) == len(expected), (eps, got, expected)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-8)
        assert got == sorted(got)
        for k, p in enumerate(bps):
            assert trivial_index(p.params["P"] - 1e-3, eps) == k
            assert br.transition(p) == f"{k} -> {k + 1}", (eps, k, br.transition(p))
        for p in br.points:
            assert "index disagreement" not in p.note
            if p.type != "BP":
                assert p.index == trivial_index(p.params["P"], eps), (eps, p.params["P"])


def test_switched_branches_are_mirror_image_buckled_rods(trivial_buckling):
    """theta -> -theta maps solutions to solutions when psi = alpha = theta0 = 0 (sin is odd):
    the two directions leaving a branch point are mirror images. Both end at the bound P = 30,
    where they must be the same rod reflected, and a nontrivial equilibrium (shooting)."""
    trivial, switched = _trivial_and_switched(trivial_buckling)
    bps = {p.name: p for br in trivial for p in br.points if p.type == "BP"}
    assert set(switched) == set(bps)
    grid = trivial_buckling.file.profile_grid
    for name, pair in switched.items():
        assert set(pair) == {1, -1}
        bp = bps[name]
        eps, Pc = bp.params["eps"], bp.params["P"]
        ends = {}
        for d, br in pair.items():
            assert br.singular_start and br.end == "EP"
            pts = br.points
            assert pts[0].params["P"] == Pc
            # supercritical: the buckled rods exist on the side P > P_cr
            assert all(p.params["P"] > Pc for p in pts[1:])
            m0 = np.array([p.ordinates["m0"] for p in pts[1:]])
            assert np.all(np.abs(m0) > 0) and len(set(np.sign(m0))) == 1
            end = pts[-1]
            assert end.type == "EP" and end.params["P"] == pytest.approx(30.0, abs=1e-9)
            ends[d] = end
        up, down = ends[1], ends[-1]
        assert abs(up.ordinates["m0"]) > 1.0     # far from the straight rod
        assert up.ordinates["m0"] == pytest.approx(-down.ordinates["m0"], abs=1e-6)
        np.testing.assert_allclose(up.state(grid)[:2], -down.state(grid)[:2], rtol=0, atol=1e-6)
        # an independent solve at the same (P, eps): Newton on the shooting residual from m0,
        # within 10x the documented accuracy of points (options.py: ~1e-7 relative)
        k0 = shooting.solve_at(0.0, 30.0, eps, up.ordinates["m0"])
        assert k0 == pytest.approx(up.ordinates["m0"], rel=0, abs=1e-6 * (1 + abs(k0)))


def test_buckled_branches_inherit_the_index_below_their_branch_point(trivial_buckling):
    """A supercritical pitchfork: the straight rod's index goes k -> k + 1 at the k + 1-th
    critical load and the buckled branch carries k: 0 (stable) from the first branch point,
    1 from the second. Checked against the dense count on every stored profile too."""
    trivial, switched = _trivial_and_switched(trivial_buckling)
    bps = {p.name: p for br in trivial for p in br.points if p.type == "BP"}
    bf = trivial_buckling.file
    stored = {b.attrs["start"] + str(b.attrs["direction"]): b for b in bf.branches}
    seen = set()
    for name, pair in switched.items():
        eps, Pc = bps[name].params["eps"], bps[name].params["P"]
        k = trivial_index(Pc - 1e-3, eps)
        seen.add(k)
        for d, br in pair.items():
            assert br.disagreements == []
            for p in br.points:
                assert "index disagreement" not in p.note
                assert p.index == k, (name, d, p.params["P"], p.index)
            for p in br.points[1:]:
                assert p.index_rule == p.index_direct == k
            b = stored[br.start + str(d)]
            for i in range(len(b)):
                count, mu_min = profile_count(bf.profile_grid, b.profiles[i],
                                              params_at(b.columns, bf.parameters, i))
                if mu_min >= MU_MIN:
                    assert count == k, (name, d, i, count)
                else:
                    # only next to the branch point, where the critical eigenvalue grows
                    # from 0 (like P - P_cr at a pitchfork)
                    assert b.columns["P"][i] - Pc < 0.1, (name, d, i, mu_min)
    assert seen == {0, 1}


def test_stored_and_exported_index_columns(trivial_buckling, cli_exe, tmp_path):
    """The file's transition column at each BP, and the CSV export's index columns on the
    straight rod, against the critical-load count."""
    bf = trivial_buckling.file
    for b in bf.branches:
        c = b.columns
        if b.attrs["start"] != "trivial":
            continue
        k = 0
        for i in np.nonzero(c["type"] == "BP")[0]:
            assert c["transition"][i] == f"{k} -> {k + 1}"
            k += 1
    out = tmp_path / "tb.csv"
    proc = run_cli(cli_exe, "export", bf.path, "-o", out)
    assert proc.returncode == 0, proc.stderr
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    trivial_numbers = {b.number for b in bf.branches if b.attrs["start"] == "trivial"}
    n = 0
    for row in rows:
        if int(row["branch"]) not in trivial_numbers or row["type"] == "BP":
            continue
        want = str(trivial_index(float(row["P"]), float(row["eps"])))
        assert row["index"] == row["index_rule"] == row["index_direct"] == want, row
        n += 1
    assert n > 100


# ---- 5. an eps-branch crosses eps = 0 without a fold ----------------------------------------

def _eps_of_k0(k0, P, psi):
    """On a psi-branch of fixed P, psi the free-end condition kappa(1) + eps P sin(psi -
    theta(1)) = 0 gives eps explicitly from the IVP with theta'(0) = k0 (alpha = theta0 = 0):
    the eps-branch is the curve k0 -> eps(k0) (while sin(psi - theta(1)) != 0), and a fold
    in eps is a sign change of d eps/d k0. Returns (eps, d eps / d k0); u = d theta / d k0."""
    th1, k1, u1, up1 = shooting.integrate(P, 0.0, 0.0, k0)
    sn, cs = math.sin(psi - th1), math.cos(psi - th1)
    return -k1 / (P * sn), -(up1 * sn + k1 * cs * u1) / (P * sn * sn)


@pytest.fixture(scope="module", params=[2.0, P1], ids=["P=2", "P=pi^2/4"])
def eps_branches(request, tmp_path_factory):
    """psi from the straight rod (eps = 0.25 at P = 2, the paper's eps = 0.5 at P = pi^2/4) to
    the user point psi = pi/2, then eps from there through 0 to the bounds [-0.6, 0.6]."""
    P = request.param
    root = tmp_path_factory.mktemp("eps_branch")
    eps0 = 0.25 if P == 2.0 else 0.5
    toml = elastica_run_file(root / "psi.toml", eps=str(eps0), P=repr(P), directions="-",
                             bounds=("-pi", "2"), uz=["pi/2"])
    psi_run = run_plan(runfile.load(toml), root)
    uz = [p for br in psi_run.result.branches for p in br.points if p.type == "UZ"]
    assert len(uz) == 1 and uz[0].params["psi"] == pytest.approx(math.pi / 2, abs=1e-12)
    (root / "eps.toml").write_text(
        'description = "eps through 0 at psi = pi/2"\nequation = "elastica_lever_arm"\n'
        f'start = "{psi_run.result.path}:{uz[0].name}"\n'
        '[continuation]\nparameter = "eps"\ndirections = "both"\nbounds = ["-0.6", "0.6"]\n')
    run = run_plan(runfile.load(root / "eps.toml"), root / "eps")
    return P, run


def test_eps_branch_crosses_eps_zero_without_a_fold_or_index_change(eps_branches):
    P, run = eps_branches
    psi = math.pi / 2
    crossings = 0
    for br, stored in zip(run.result.branches, run.file.branches):
        pts = br.points
        assert all(p.params["psi"] == psi and p.params["P"] == P for p in pts)
        assert br.disagreements == []
        # no fold labelled near eps = 0
        assert not [p for p in pts if p.type == "LP" and abs(p.params["eps"]) < 0.02]
        eps = np.array([p.params["eps"] for p in pts])
        # every point lies on the shooting curve eps(k0) at k0 = m0 (accuracy of the points:
        # free-end residual <= 1e-6 (1 + |eps P|) (test_elastica), divided by P |sin| ~ P)
        for p in pts:
            e, _ = _eps_of_k0(p.ordinates["m0"], P, psi)
            assert e == pytest.approx(p.params["eps"], abs=2e-6 / P), p.params["eps"]
        for i in np.nonzero(eps[:-1] * eps[1:] < 0)[0]:
            crossings += 1
            a, b = pts[i], pts[i + 1]
            assert a.index_direct == b.index_direct == a.index == b.index
            # the dense count either side, from the nearest points with no eigenvalue near 0
            dense = []
            for rng in (range(i, -1, -1), range(i + 1, len(pts))):
                for j in rng:
                    if abs(eps[j]) > 0.1 or pts[j].type in ("LP", "BP"):
                        break
                    count, mu_min = profile_count(run.file.profile_grid, stored.profiles[j],
                                                  pts[j].params)
                    if mu_min >= MU_MIN:
                        dense.append(count)
                        break
            assert len(dense) == 2 and dense[0] == dense[1] == a.index, dense
            if P == 2.0:
                # at eps = 0 the rod is straight (P < pi^2/4: no buckled cantilever) with
                # eigenvalues ((j - 1/2) pi)^2 - P > 0: index 0 nearby
                assert a.index == 0
    assert crossings == 1
    # (theta, eps, psi) -> (-theta, -eps, pi - psi) maps solutions to solutions (the free-end
    # term eps P sin(psi - theta(1)) is then odd, like kappa(1)), and psi = pi/2 is fixed by it:
    # the curve through eps = 0 is symmetric, its ends at eps = +-0.6 mirror images.
    ends = {round(br.points[-1].params["eps"], 12): br.points[-1] for br in run.result.branches}
    assert set(ends) == {0.6, -0.6}
    assert ends[0.6].ordinates["m0"] == pytest.approx(-ends[-0.6].ordinates["m0"], abs=1e-6)


def test_near_eps_zero_the_eps_branch_is_a_graph_over_eps(eps_branches):
    """For psi != 0 the eps-branches pass (theta'(0) = 0, eps = 0) without a fold (no sign
    change of d eps/d tau; docs/design.md, "Turning points that are not folds"). By shooting:
    eps(k0) is monotone on the k0-range the computed branch spans near eps = 0, so the branch
    is a graph over eps there and has no fold. Whether the tangent is vertical depends on P:
    d eps/d k0 at k0 = 0 is -cos(sqrt P)/(P sin psi), zero only at the eps = 0 buckling loads
    ((2j - 1) pi / 2)^2.
    So at P = pi^2/4 (the paper's load) the crossing is a vertical inflection (eps ~ k0^3),
    while at P = 2 it is transversal (eps ~ k0): the starting design's claim that it is
    always vertical holds only at those loads."""
    P, run = eps_branches
    psi = math.pi / 2
    m0 = [p.ordinates["m0"] for br in run.result.branches for p in br.points
          if abs(p.params["eps"]) < 0.05]
    lo, hi = min(m0) - 0.05, max(m0) + 0.05
    assert lo < 0 < hi
    k0 = np.linspace(lo, hi, 41)
    slopes = np.array([_eps_of_k0(k, P, psi)[1] for k in k0])
    e0, slope0 = _eps_of_k0(0.0, P, psi)
    assert e0 == 0.0
    assert slope0 == pytest.approx(-math.cos(math.sqrt(P)) / (P * math.sin(psi)), abs=1e-10)
    if P == 2.0:
        assert np.all(slopes < 0), slopes          # transversal: eps is a coordinate
    else:
        assert abs(slope0) < 1e-10                  # vertical tangent at k0 = 0 ...
        away = np.abs(k0) > 1e-3
        assert np.all(slopes[away] < 0), slopes     # ... but no sign change: an inflection


# ---- 6. every fold: the transition against the dense count on either side --------------------

def _fold_checks(run):
    bf = run.file
    grid = bf.profile_grid
    checked = 0
    for b in bf.branches:
        c = b.columns
        types = c["type"]
        for i in np.nonzero(types == "LP")[0]:
            side = []
            for rng in (range(i - 1, -1, -1), range(i + 1, len(b))):
                for j in rng:
                    assert types[j] not in ("LP", "BP"), "no regular point between two folds"
                    count, mu_min = profile_count(grid, b.profiles[j],
                                                  params_at(c, bf.parameters, j))
                    if mu_min >= MU_MIN:
                        side.append(count)
                        break
            assert len(side) == 2, (b.number, i)
            before, after = _transition(c["transition"][i])
            assert (before, after) == tuple(side), (b.number, i, c["transition"][i], side)
            assert abs(before - after) == 1
            checked += 1
    return checked


def test_fold_transitions_match_the_dense_count_on_either_side(rotating_arm, trivial_buckling):
    assert _fold_checks(rotating_arm) >= 40
    # the P-branches of trivial_buckling have no folds: the straight rod is parameterised by P
    # itself, and the buckled branches leave supercritical pitchforks with P increasing
    assert _fold_checks(trivial_buckling) == 0


def test_smallest_eigenvalue_of_small_blocks_matches_lapack():
    """The closed forms of the 2 x 2 and 3 x 3 smallest eigenvalue (stability.min_eig)
    against LAPACK's, on random symmetric blocks and on rotated diag(1, 1, c) and diag(c, c, 1)
    (a double eigenvalue above or at the bottom: the arccos is steep there), to rounding."""
    rng = np.random.default_rng(7)
    for k in (2, 3):
        x = rng.normal(size=(300, k, k))
        blocks = [x @ x.transpose(0, 2, 1) + 0.1 * np.eye(k), 2.5 * np.broadcast_to(
            np.eye(k), (5, k, k)).copy()]
        if k == 3:
            q, _ = np.linalg.qr(rng.normal(size=(300, 3, 3)))
            for diag in ((1.0, 1.0, 1 / 1.3), (0.5, 0.5, 1.0), (0.5, 0.5 + 1e-9, 1.0)):
                blocks.append((q * np.array(diag)) @ q.transpose(0, 2, 1))
        for a in blocks:
            ref = np.linalg.eigvalsh(a)
            err = np.abs(stability.min_eig(a) - ref[:, 0]) / np.abs(ref).max(axis=1)
            assert np.max(err) < 1e-14, (k, np.max(err))


def test_smallest_eigenvalue_of_blocks_with_a_decoupled_stiff_component():
    """A 3 x 3 block with one component decoupled (both its off-diagonal entries zero) and
    stiff (S = 1e3 and 1e6, as a Cosserat rod's shear stiffness next to its bending
    stiffnesses, in each of the three places): its two smallest eigenvalues are close
    relative to S, where the trigonometric form loses digits. The eigenvalues of a block
    diagonal matrix are its blocks' together: the result is the smaller of S and LAPACK's
    smallest of the soft 2 x 2 block, to rounding relative to that block (not to S; LAPACK on
    the whole block is accurate only to rounding relative to S). Also with the decoupled
    component the softest (its diagonal the answer)."""
    rng = np.random.default_rng(11)
    for stiff in (1e3, 1e6, 0.01):
        for j in range(3):
            x = rng.normal(size=(200, 2, 2))
            soft = x @ x.transpose(0, 2, 1) + 0.1 * np.eye(2)
            rest = [i for i in range(3) if i != j]
            a = np.zeros((200, 3, 3))
            a[:, j, j] = stiff
            a[np.ix_(range(200), rest, rest)] = soft
            ref = np.minimum(stiff, np.linalg.eigvalsh(soft)[:, 0])
            err = np.abs(stability.min_eig(a) - ref) / np.abs(np.linalg.eigvalsh(soft)).max(
                axis=1)
            assert np.max(err) < 1e-14, (stiff, j, np.max(err))
            # decoupled at some points only (the others coupled to the stiff component): each
            # point's own answer, LAPACK's where coupled
            mixed = a.copy()
            mixed[::3, j, rest[1]] = mixed[::3, rest[1], j] = 0.3
            ref = ref.copy()
            ref[::3] = np.linalg.eigvalsh(mixed[::3])[:, 0]
            err = np.abs(stability.min_eig(mixed) - ref) / np.abs(
                np.linalg.eigvalsh(mixed)).max(axis=1)
            assert np.max(err) < 1e-14, (stiff, j, np.max(err))


def test_the_rates_by_the_adjugate_match_a_solve():
    """The refinement's rates (stability.rates) with A^-1 C by the adjugate (k = 2, 3,
    compiled) against numpy's solve, on random positive definite A and any C, to rounding;
    the fields laid out as the count hands them (views with any strides: every other point
    of a larger array, the hook's (k, k, P) transposed)."""
    rng = np.random.default_rng(5)
    for k in (2, 3):
        x = rng.normal(size=(101, k, k))
        a = x @ x.transpose(0, 2, 1) + 0.5 * np.eye(k)
        b, c = rng.normal(size=(2, 101, k, k))
        b = b + b.transpose(0, 2, 1)
        a_min = np.linalg.eigvalsh(a)[:, 0]
        turn = np.linalg.solve(a, c)
        frobenius = lambda m: np.sqrt(np.sum(m * m, axis=(-2, -1)))  # noqa: E731
        ref = np.sqrt(frobenius(b - c.transpose(0, 2, 1) @ turn) / a_min) + frobenius(turn)
        assert np.allclose(stability.rates(a, a_min, b, c), ref, rtol=1e-12, atol=0)
        strided = [np.repeat(m.transpose(1, 2, 0), 2, axis=2).transpose(2, 0, 1)[::2]
                   for m in (a, b, c)]
        assert np.allclose(stability.rates(strided[0], a_min, *strided[1:]), ref, rtol=1e-12,
                           atol=0)


def test_the_rule_past_a_branch_point_followed_by_a_fold_reads_the_count_beyond_it():
    """A BP, then at once an LP (rotating_arm_3d has an out-of-plane BP at psi = -pi and an
    in-plane fold 0.02 beyond it, with no point between): the index between them is the
    count past the fold less the fold's change, not the LP's own count, which is taken at a
    zero eigenvalue (a guess by rounding, or -1). Here the fold takes 5 to 4 (psi turns back,
    its curvature < 0 and the ordinate's slope > 0: index_change = -1)."""
    from types import SimpleNamespace as NS
    lam, ordinate = [0.0, 1.0, 2.0, 1.5, 1.0], [0.0, 0.0, 1.0, 2.0, 3.0]
    types = ["", "BP", "LP", "", ""]
    for lp_count in (-1, 3, 5):        # whatever the count at the fold's own state says
        direct = [4, -1, lp_count, 4, 4]
        points = [NS(type=t, index_direct=d) for t, d in zip(types, direct)]
        branch = NS(parameter="psi", points=points,
                    column=lambda name: np.array(lam if name == "psi" else ordinate))
        problem = NS(ordinates={"m": NS(name="m", parameter="psi")},
                     parameters={"psi": NS(enters="free")})
        assert stability.fold_sign("free", np.array(lam), np.array(ordinate), 2) == -1
        assert stability.fold_rule(branch, problem, 4) == [4, 4, 5, 4, 4], lp_count


def test_where_the_rule_cannot_apply_it_restarts_past_a_following_fold_too():
    """The same restart where the rule stops at an LP it cannot sign (psi's curvature zero
    there) followed at once by an LP that takes 5 to 4: the index between the two is the
    count past the second less its change, whatever the second's own count says."""
    from types import SimpleNamespace as NS
    lam, ordinate = [0.0, 1.0, 2.0, 1.5, 1.0], [0.0, 1.0, 0.0, 2.0, 3.0]
    for lp_count in (-1, 3, 5):
        direct = [4, -1, lp_count, 4, 4]
        points = [NS(type=t, index_direct=d) for t, d in zip(["", "LP", "LP", "", ""], direct)]
        branch = NS(parameter="psi", points=points,
                    column=lambda name: np.array(lam if name == "psi" else ordinate))
        problem = NS(ordinates={"m": NS(name="m", parameter="psi")},
                     parameters={"psi": NS(enters="free")})
        assert stability.fold_sign("free", np.array(lam), np.array(ordinate), 1) == 0
        assert stability.fold_sign("free", np.array(lam), np.array(ordinate), 2) == -1
        assert stability.fold_rule(branch, problem, 4)[2:] == [5, 4, 4], lp_count


def test_a_form_without_legendre_names_its_module_once():
    """Hostile turn 5, L14: the spatial rod's own counts (count_form without a module's name)
    failed with "second_variation: second_variation: A is not positive definite". The
    name is given once, or not at all."""
    from elastica_auto import SecondVariation
    from elastica_auto.numerics.stability import LegendreError, count_form
    mesh = np.linspace(0, 1, 11)

    def form(pts):              # A = -1 + 2 s: negative on [0, 1/2)
        return SecondVariation(-1 + 2 * pts, 0.0, fixed0=[0], fixed1=[0])

    with pytest.raises(LegendreError) as bare:
        count_form(form, mesh)
    assert str(bare.value).startswith("second_variation: A is not positive definite at s = 0")
    with pytest.raises(LegendreError) as named:
        count_form(form, mesh, source="mod")
    assert str(named.value) == "mod: " + str(bare.value)


def test_folds_and_branch_points_are_not_counted_where_a_neighbour_pair_shows_the_crossing(
        rotating_arm):
    """An LP or BP row is singular by construction: its direct count, which would read the
    sign of a zero eigenvalue from rounding, is -1, and `index` there is the rule's. Each
    fold's two neighbours are counted and differ by one (the eigenvalue that crosses zero at
    the row between them)."""
    seen = 0
    for br in rotating_arm.result.branches:
        pts = br.points
        for k, p in enumerate(pts):
            if p.type not in ("LP", "BP"):
                continue
            assert p.index_direct == -1, (p.name, p.index_direct)
            assert p.index == p.index_rule, p.name
            if p.type == "LP" and 0 < k < len(pts) - 1:
                before, after = pts[k - 1].index_direct, pts[k + 1].index_direct
                assert before >= 0 and after >= 0 and abs(before - after) == 1, p.name
                seen += 1
    assert seen >= 4


def test_a_spatial_rods_fold_has_no_part_counted_either():
    """The spatial rod through its first folds (b2 = 2): on the LP rows the whole count and
    each part's (index_in, index_out) are -1; beside them both parts are counted, and the
    in-plane part is the one that changes across the fold."""
    import elastica_auto as ea
    rod = ea.load_problem("kirchhoff_lever_arm")
    params = {"eps": 0.25, "P": math.pi ** 2 / 4, "psi": 0.0, "alpha": 0.0, "theta0": 0.0,
              "b2": 2.0}
    plus, = ea.continuation(rod, params, "psi", bounds=(-2.0, 2.0), directions="+")
    pts, folds = plus.points, 0
    for k, p in enumerate(pts):
        if p.type != "LP":
            continue
        assert p.index_direct == -1
        assert p.ordinates["index_in"] == p.ordinates["index_out"] == -1
        if 0 < k < len(pts) - 1:
            a, b = pts[k - 1].ordinates, pts[k + 1].ordinates
            assert min(a["index_in"], b["index_in"], a["index_out"], b["index_out"]) >= 0
            assert abs(a["index_in"] - b["index_in"]) == 1
            assert a["index_out"] == b["index_out"]
            folds += 1
    assert folds >= 1
