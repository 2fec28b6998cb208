"""The numerics that every module derived from an energy shares (numpy and scipy only).

A generated module (`elastica_auto.energy.codegen`) writes its formulas out and calls these for
what is not a formula:

* :func:`legendre_inverse`: zeta' from the momenta where the density is not quadratic in
  zeta', by Newton's method on the strictly convex ``phi(v) = L(zeta, v, s) - m.v`` (its
  minimiser solves ``dL/dv = m``), with a backtracking line search, point by point;
* :func:`hamilton_jacobian`, :func:`hamilton_dp`: the Jacobians of ``zeta' = V(zeta, m)``,
  ``m' = L_zeta``, ``x' = g`` by the implicit function theorem (``dV/dm = A^-1``, ``dV/dzeta
  = -A^-1 C``, ``dV/dp = -A^-1 L_vp``; ``A = L_vv``, ``C = L_vz``);
* :func:`acceleration`: zeta'' along a solution, for a constraint whose rate contains zeta';
* :func:`integrals`: the ordinates that are integrals, by Simpson's rule on the solution's
  Hermite cubics (4th order, as the solution);
* :func:`gradient_flow`: the energy discretised on a grid (midpoint rule) and its
  overdamped dynamics, for where a snap lands (`elastica_auto.analysis.landing`);
* :func:`part_count`: the index of a named part of the second variation, as an ordinate;
* :func:`zero_modes`, :func:`spatial_turn`: a symmetry's zero mode in the perturbations (a
  rotation's by its spatial turn).
"""

from __future__ import annotations

import functools

import numpy as np

from ._frames import body as _body, chain as _chain, frame as _frame
from ._frames import quaternion_rate as _quaternion_rate

#: The prefix of a generated module's own top-level helpers (`elastica_auto.energy.codegen`);
#: a module with ENERGY may not define such names itself.
PREFIX = "_derived_"
#: The last line of every generated module: a cached file without it was cut short.
TRAILER = "# (the end of the derived module)"

#: Newton's method for the Legendre inverse stops at a point where |dL/dv - m| <= RESIDUAL
#: (1 + |m|), where its step is at rounding level, where the quadratic rate says the step
#: just taken was the last (FINAL) or where the steps stall at rounding's size (STALL); at
#: most ITERATIONS steps, each with at most HALVINGS halvings of the line search. A point
#: that does not converge is NaN: the engine's corrector sees a non-finite residual and
#: shortens its step.
RESIDUAL = 1e-14
ITERATIONS = 50
HALVINGS = 40
#: A full Newton step ``delta`` after full steps ``delta_1``, ``delta_0`` is the last where
#: the next one, about ``C delta^2`` by the quadratic rate with ``C`` the larger of
#: ``delta / delta_1^2`` and ``delta_1 / delta_0^2``, is below FINAL (1 + |v|).
FINAL = 1e-15
#: Full steps under STALL (1 + |v|) that shrink less than twofold are rounding's noise.
STALL = 1e-12


def _solve(a, b):
    """a^-1 b for a (k, k, m) and b (k, m) or (k, j, m), point by point."""
    if a.shape[0] == 1:
        return b / a[0, 0] if b.ndim == 2 else b / a[0, 0][None, None]
    am = np.moveaxis(a, -1, 0)
    if b.ndim == 2:
        return np.moveaxis(np.linalg.solve(am, np.moveaxis(b, -1, 0)[..., None])[..., 0], 0, -1)
    return np.moveaxis(np.linalg.solve(am, np.moveaxis(b, -1, 0)), 0, -1)


def legendre_inverse(legendre, s, z, m, p, far=False):
    """v with dL/dv (z, v, s) = m at every point, (k, m'): ``legendre(s, z, v, p)`` returns
    L (m'), dL/dv (k, m') and d2L/dv2 (k, k, m'). NaN where it does not converge or
    d2L/dv2 is not positive definite (the derivation checked convexity at samples only).

    Newton starts at v = 0, except where L or its derivatives are not finite there: a density
    with the length of a vector of the velocities (a tendon's |v + u x d|, with v = R^T r') is
    not differentiable where that vector vanishes, which for a rod is r' = 0, u = 0. There it
    starts far out, at v = 1e3 (1, ..., 1): a norm's gradient is bounded (tau) and its
    curvature tau / |t| small there, so the first step lands near the minimiser of the
    quadratic part with the norms linearised, on the side of each kink where the solution
    is. Started near a kink instead (v = (1, ..., 1) in a turned frame), Newton can walk into
    it and stick: across the kink the Hessian is unbounded and the steps vanish. A minimiser
    at a kink (a tendon of zero length) is not found at all (the residual does not vanish
    there): NaN.

    ``far``: the generator found dL/dv not finite at v = 0 for every state (`codegen._far`):
    the start is far out at every point, without the evaluation at 0 that would say so."""
    z, m = np.asarray(z, dtype=float), np.asarray(m, dtype=float)
    k, npts = m.shape
    s = np.broadcast_to(np.asarray(s, dtype=float), (npts,))
    if far:
        v = np.full((k, npts), 1e3)
        singular = np.ones(npts, dtype=bool)
    else:
        v = np.zeros((k, npts))
        with np.errstate(all="ignore"):
            L, Lv, Lvv = legendre(s, z, v, p)
        singular = ~(np.isfinite(L) & np.all(np.isfinite(Lv), axis=0)
                     & np.all(np.isfinite(Lvv), axis=(0, 1)))
        v[:, singular] = 1e3
    if np.any(singular):
        L, Lv, Lvv = legendre(s, z, v, p)
    phi = L - np.sum(m * v, axis=0)
    done = np.zeros(npts, dtype=bool)
    bad = np.zeros(npts, dtype=bool)
    last = np.full(npts, np.inf)          # the previous full Newton step's size (inf: none)
    last2 = np.full(npts, np.inf)         # and the one before it
    for iteration in range(ITERATIONS):
        r = Lv - m
        with np.errstate(all="ignore"):
            step = _solve(Lvv, r)
        if k == 1:
            bad |= ~(Lvv[0, 0] > 0)
        big = np.max(np.abs(step), axis=0)
        scale = 1 + np.max(np.abs(v), axis=0)
        size = np.max(np.abs(r), axis=0) / (1 + np.max(np.abs(m), axis=0))
        done |= (size <= RESIDUAL) | (big <= 1e-15 * scale)
        done &= ~bad
        # Newton's quadratic rate: the step after this one is about C big^2, C estimated
        # from the last three full steps, the larger of big / last^2 and last / last2^2
        # (near a kink C grows as the tendon shortens, and a step that was not yet in the
        # quadratic regime makes big / last^2 too small: the two must both be seen); where
        # C big^2 would be at rounding level and the step shrank 1000-fold, this step is
        # the last: taken in full, unchecked, which saves the evaluation that would only
        # confirm it. (The first step from far out is none of Newton's quadratic rate.)
        # Where the full steps stopped shrinking at a size of rounding's (STALL), the
        # residual within 1000 RESIDUAL, Newton is at the floor of dL/dv's rounding, which
        # for large terms (a stiffness S = 1000 times a strain) lies above RESIDUAL (1 +
        # |m|): done, not NaN. (At a kink the steps vanish too, but the residual does not.)
        with np.errstate(all="ignore"):
            rate = np.maximum(big / (last * last), last / (last2 * last2))
            final = ~(done | bad) & np.isfinite(last2) & (big <= 1e-3 * last) \
                & (rate * big * big <= FINAL * scale)
            done |= ~bad & (big <= STALL * scale) & (big >= 0.5 * last) \
                & (size <= 1e3 * RESIDUAL)
        final &= ~done
        v[:, final] -= step[:, final]
        done |= final
        if np.all(done | bad):
            break
        t = np.where(done | bad | ~np.isfinite(big), 0.0, 1.0)
        slope = np.sum(r * step, axis=0)
        for _ in range(HALVINGS):
            trial = v - t * np.nan_to_num(step)
            Lt, Lvt, Lvvt = legendre(s, z, trial, p)
            phit = Lt - np.sum(m * trial, axis=0)
            ok = (phit <= phi - 1e-4 * t * slope + 1e-14 * np.abs(phi)) | (t == 0.0) \
                | (t * big <= 1e-10 * (1 + np.max(np.abs(v), axis=0)))
            if np.all(ok):
                break
            t = np.where(ok, t, 0.5 * t)
        # (the first step from far out is no step of Newton's quadratic rate)
        full = (t == 1.0) & ~(singular & (iteration == 0))
        last2 = np.where(full, last, np.inf)
        last = np.where(full, big, np.inf)
        v, L, Lv, Lvv, phi = trial, Lt, Lvt, Lvvt, phit
    else:
        r = Lv - m
        done |= np.max(np.abs(r), axis=0) <= RESIDUAL * (1 + np.max(np.abs(m), axis=0))
    v[:, ~done | bad] = np.nan
    return v


def remembered(solve, s, y, p):
    """``solve(s, y, p)`` (a generated module's Newton velocity), read-only, remembered for
    the last few arguments: the engine asks rhs, rhs_jac, rhs_dp and the second variation
    at the same points one after the other (at a tendon robot's point, a third of the
    Legendre inverses were repeats), and each would solve again. A pure function of its
    arguments (keyed by their bytes), so the order work is done in changes no result."""
    s, y = np.asarray(s, dtype=float), np.ascontiguousarray(y, dtype=float)
    items = tuple(sorted(p.items()))
    try:
        hash(items)
    except TypeError:                  # a parameter that is an array: not remembered
        return solve(s, y, p)
    return _remembered(solve, s.shape, s.tobytes(), y.shape, y.tobytes(), items)


@functools.lru_cache(maxsize=16)
def _remembered(solve, s_shape, s_bytes, y_shape, y_bytes, items):
    s = np.frombuffer(s_bytes).reshape(s_shape).copy()
    y = np.frombuffer(y_bytes).reshape(y_shape).copy()
    out = solve(s, y, dict(items))
    out.flags.writeable = False
    return out


def hamilton_jacobian(A, C, B, gz, gv):
    """df/dy (n, n, m) of zeta' = V, m' = L_z, x' = g with the states (zeta, m, x): A = L_vv,
    C = L_vz (rows v, columns zeta), B = L_zz, each (k, k, m); gz, gv (nq, k, m)."""
    k, _, npts = A.shape
    nq = gz.shape[0]
    n = 2 * k + nq
    ainv = _solve(A, np.broadcast_to(np.eye(k)[:, :, None], (k, k, npts)))
    dvdz = -np.einsum("ijm,jlm->ilm", ainv, C)
    ct = C.transpose(1, 0, 2)
    jac = np.zeros((n, n, npts))
    jac[:k, :k] = dvdz
    jac[:k, k:2 * k] = ainv
    jac[k:2 * k, :k] = B + np.einsum("ijm,jlm->ilm", ct, dvdz)
    jac[k:2 * k, k:2 * k] = np.einsum("ijm,jlm->ilm", ct, ainv)
    if nq:
        jac[2 * k:, :k] = gz + np.einsum("ijm,jlm->ilm", gv, dvdz)
        jac[2 * k:, k:2 * k] = np.einsum("ijm,jlm->ilm", gv, ainv)
    return jac


def hamilton_dp(A, C, gv, Lzp, Lvp, gp):
    """df/dp (n, m) of the same system: dV/dp = -A^-1 L_vp."""
    dvdp = -_solve(A, Lvp)
    return np.concatenate((dvdp, Lzp + np.einsum("jim,jm->im", C, dvdp),
                           gp + np.einsum("qjm,jm->qm", gv, dvdp)))


def acceleration(density, lvs, s, z, v, p):
    """zeta'' along a solution (k, m): differentiating m = L_v(zeta, zeta', s) gives
    m' = C zeta' + A zeta'' + L_vs, and m' = L_z, so zeta'' = A^-1 (L_z - C zeta' - L_vs)."""
    _, Lz, _, _, Lvz, Lvv = density(s, z, v, p)
    return _solve(Lvv, Lz - np.einsum("ijm,jm->im", Lvz, v) - lvs(s, z, v, p))


def field(rows, m):
    """A (k, k) matrix of entries that are numbers or arrays on m points: (k, k) where all
    are numbers, else (k, k, m). The generated second variation writes every entry, most of
    them often a literal 0 (the spatial Cosserat rod's A, B and C: 74 of 108; its end terms
    E0, E1: most of 72): those are the array's initial zeros, and only the others are written
    (a numpy call each, which on a few hundred points costs more than the arithmetic; and
    numpy's conversion of a nested list of numbers costs more than writing the few nonzero
    ones into zeros)."""
    given = [(i, j, v) for i, row in enumerate(rows) for j, v in enumerate(row)
             if type(v) is not int or v]
    arrays = any(isinstance(v, np.ndarray) and v.ndim for _, _, v in given)
    out = np.zeros((len(rows), len(rows[0]), m) if arrays else (len(rows), len(rows[0])))
    for i, j, v in given:
        out[i, j] = v
    return out


def at_end(g, j):
    """A vector field (k,) or (k, m) at the point j."""
    return g if g.ndim == 1 else g[:, j]


def integrals(s, y, p, rhs, velocity, integrands):
    """int_0^1 of each of ``integrands(s, y, v, p)`` (q, m) at the solution y on the nodes s:
    Simpson's rule on each interval, the midpoint values from the Hermite cubic of the
    solution (slopes rhs), the velocities v (zeta' and the strains) from ``velocity``.
    Cached for the few ordinates asked for one after the other at the same point."""
    s, y = np.ascontiguousarray(s, dtype=float), np.ascontiguousarray(y, dtype=float)
    return _integrals(s.tobytes(), y.tobytes(), y.shape[0], tuple(sorted(p.items())), rhs,
                      velocity, integrands)


@functools.lru_cache(maxsize=8)
def _integrals(s_bytes, y_bytes, n, items, rhs, velocity, integrands):
    from ..core.solution import at_fractions
    s = np.frombuffer(s_bytes).copy()
    y = np.frombuffer(y_bytes).reshape(n, -1).copy()
    p = dict(items)
    ym = at_fractions(s, y, rhs(s, y, p), (0.5,))[:, 0]
    sm = 0.5 * (s[:-1] + s[1:])
    f = integrands(s, y, velocity(s, y, p), p)
    fm = integrands(sm, ym, velocity(sm, ym, p), p)
    out = np.sum(np.diff(s) * (f[:, :-1] + 4 * fm + f[:, 1:]), axis=1) / 6
    out.flags.writeable = False
    return out


def part_count(second_variation, rhs, name, count_form):
    """An ordinate fn(s, y, p): the index of the part ``name`` of the second variation at the
    solution (-1 where the form does not decouple or the part has a zero eigenvalue), by the
    engine's ``count_form`` (`elastica_auto.numerics.stability`, which the generated module
    passes). The engine fills these ordinates itself along a branch; this is for elsewhere
    (snap-back targets, mirror images)."""
    def fn(s, y, p):
        s, y = np.ascontiguousarray(s, dtype=float), np.ascontiguousarray(y, dtype=float)
        return part_counts(s.tobytes(), y.tobytes(), y.shape[0], tuple(sorted(p.items())),
                            second_variation, rhs, count_form)[name]
    return fn


@functools.lru_cache(maxsize=4)
def part_counts(s_bytes, y_bytes, n, items, second_variation, rhs, count_form):
    """The index of each part of the second variation at the solution given by its mesh's
    and states' bytes and its parameters' items (hashable, so that the ordinates of one
    point count it once): `part_count`'s ordinates read it."""
    from ..core.solution import State
    s = np.frombuffer(s_bytes).copy()
    y = np.frombuffer(y_bytes).reshape(n, -1).copy()
    p = dict(items)
    state = State(s, y, rhs(s, y, p), p)
    return count_form(lambda pts: second_variation(pts, state(pts), p), s).parts


def gradient_flow(p, nodes, density, ends, essential, k, flow, rows):
    """The energy at ``p`` discretised on ``nodes`` and its overdamped dynamics, as an
    `elastica_auto.analysis.landing.Flow`.

    u is the coordinates at the nodes, those held by an essential end value left out,
    component after component. The energy is the midpoint rule on each interval,
    ``E_h(u) = sum_j h_j L(zbar_j, (z_{j+1} - z_j) / h_j, sbar_j) + B0(z_0) + B1(z_N) + c``
    (second order; ``L`` with the quadratures' terms, ``c`` their constant), and
    ``u_t = -M^-1 grad E_h`` with M the lumped (trapezoidal) mass. Its Jacobian is the
    block-tridiagonal Hessian, assembled from each interval's (2k, 2k) block; k is the
    number of coordinates, ``rows`` their rows in the states, ``flow`` the class
    `elastica_auto.Flow` (the generated module passes it: this package sits below the
    analysis layer)."""
    from scipy.sparse import coo_matrix

    from ..core.solution import trapezoid_weights
    nodes = np.asarray(nodes, dtype=float)
    fixed0, fixed1, constant = essential(p)
    npts = len(nodes)
    h = np.diff(nodes)
    sm = 0.5 * (nodes[:-1] + nodes[1:])
    weights = trapezoid_weights(nodes)
    keep = np.ones((k, npts), dtype=bool)
    full = np.zeros((k, npts))
    for i, value in fixed0.items():
        keep[i, 0], full[i, 0] = False, value
    for i, value in fixed1.items():
        keep[i, -1], full[i, -1] = False, value
    free = np.flatnonzero(keep.ravel())
    mass = np.tile(weights, k)[free]

    def configuration(u):
        z = full.copy().ravel()
        z[free] = u
        return z.reshape(k, npts)

    def pieces(u):
        z = configuration(u)
        zm, vm = 0.5 * (z[:, :-1] + z[:, 1:]), np.diff(z, axis=1) / h
        return z, density(sm, zm, vm, p)

    def energy(u):
        z, (L, *_) = pieces(u)
        (b0, _, _), (b1, _, _) = ends(z[:, 0], z[:, -1], p)
        return float(np.sum(h * L) + b0 + b1 + constant)

    def gradient(u):
        z, (_, Lz, Lv, *_) = pieces(u)
        g = np.zeros((k, npts))
        g[:, :-1] += 0.5 * h * Lz - Lv
        g[:, 1:] += 0.5 * h * Lz + Lv
        (_, b0z, _), (_, b1z, _) = ends(z[:, 0], z[:, -1], p)
        g[:, 0] += b0z
        g[:, -1] += b1z
        return g.ravel()[free]

    def hessian(u):
        z, (_, _, _, Lzz, Lvz, Lvv) = pieces(u)
        Lzv = Lvz.transpose(1, 0, 2)
        hq = h / 4 * Lzz
        aa = hq - 0.5 * (Lzv + Lvz) + Lvv / h
        bb = hq + 0.5 * (Lzv + Lvz) + Lvv / h
        ab = hq + 0.5 * (Lzv - Lvz) - Lvv / h
        j = np.arange(npts - 1)
        rows, cols, vals = [], [], []
        for a in range(k):
            for b in range(k):
                for block, ra, cb in ((aa, j, j), (bb, j + 1, j + 1), (ab, j, j + 1),
                                      (ab.transpose(1, 0, 2), j + 1, j)):
                    rows.append(a * npts + ra)
                    cols.append(b * npts + cb)
                    vals.append(block[a, b])
        (_, _, b0zz), (_, _, b1zz) = ends(z[:, 0], z[:, -1], p)
        for a in range(k):
            for b in range(k):
                rows += [np.array([a * npts]), np.array([a * npts + npts - 1])]
                cols += [np.array([b * npts]), np.array([b * npts + npts - 1])]
                vals += [np.array([b0zz[a, b]]), np.array([b1zz[a, b]])]
        size = k * npts
        full_h = coo_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                    np.concatenate(cols))),
                            shape=(size, size)).tocsr()
        return full_h[free][:, free]

    def force(u):
        return -gradient(u) / mass

    def jacobian(u):
        from scipy.sparse import diags
        return (-diags(1.0 / mass) @ hessian(u)).tocsc()

    return flow(nodes, lambda y: np.asarray(y)[rows].ravel()[free], mass, energy, force,
                jacobian)



#: A symmetry's zero mode is left out of the count where its L2 size on the points exceeds
#: this: below it the state is one the group fixes (the straight rod), where it is no mode.
ZERO_MODE = 1e-6


def zero_modes(symmetry, s, y, p, tangent, constraint) -> list:
    """[constraint(z, kernel=True)] where the module's ``symmetry`` hook holds at y, z the
    zero mode of the group in the perturbations (``tangent(y, generator)``: the
    coordinates' rows, a rotation's spatial turn), L2-normalised on the points s; else []:
    a derived second variation on a circle of solutions is counted on the complement of
    its zero mode (docs/stability.md, "Continuous symmetry"). ``constraint`` is
    `elastica_auto.Constraint`, which the generated module passes."""
    if symmetry is None:
        return []
    found = symmetry(s, y, p)
    if found is None:
        return []
    from ..core.solution import trapezoid_weights
    z = tangent(y, np.asarray(found.generator, dtype=float))
    size = float(np.sqrt(trapezoid_weights(s) @ np.sum(z * z, axis=0)))
    if not size > ZERO_MODE:
        return []
    return [constraint(z / size, kernel=True)]


def spatial_turn(q, dq):
    """The spatial rotation w (3, m) of a change dq of the quaternions q (4, m): [w]_x =
    dR R^T, w = 2 Im(dq (x) conj(q)) / |q|^2."""
    q0, q1, q2, q3 = q
    d0, d1, d2, d3 = dq
    scale = 2 / (q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    return np.array((-d0 * q1 + d1 * q0 - d2 * q3 + d3 * q2,
                     -d0 * q2 + d2 * q0 - d3 * q1 + d1 * q3,
                     -d0 * q3 + d3 * q0 - d1 * q2 + d2 * q1)) * scale


def _quadratic_tensor():
    """T (4, 3, 3, 4): dQ(q)/dq_j = 2 T[j] @ q, Q(q) the rotation matrix of q times |q|^2
    (each entry of Q is q.T_ab q, T_ab symmetric)."""
    t = np.zeros((4, 3, 3, 4))
    for j, rows in enumerate((
            (((0, 1), (3, -1), (2, 1)), ((3, 1), (0, 1), (1, -1)), ((2, -1), (1, 1), (0, 1))),
            (((1, 1), (2, 1), (3, 1)), ((2, 1), (1, -1), (0, -1)), ((3, 1), (0, 1), (1, -1))),
            (((2, -1), (1, 1), (0, 1)), ((1, 1), (2, 1), (3, 1)), ((0, -1), (3, 1), (2, -1))),
            (((3, -1), (0, -1), (1, 1)), ((0, 1), (3, -1), (2, 1)), ((1, 1), (2, 1), (3, 1))))):
        for a in range(3):
            for b in range(3):
                c, sign = rows[a][b]
                t[j, a, b, c] = sign
    t.flags.writeable = False
    return t


#: D[j, a, b, c]: (1/2) dQ_ab/dq_j = D[j, a, b] @ q (linear in q), and Q = sum_j q_j D_j q
#: (Euler's relation): R and dR/dq by one matrix product each (`frame`, `chain`).
_D = _quadratic_tensor()
_QUADRATIC = _D.transpose(1, 2, 0, 3).reshape(9, 16)     # Q = _QUADRATIC @ (q (x) q)
_LINEAR = _D.reshape(36, 4)                               # D_j(q) = (_LINEAR @ q)[j, a, b]


def frame(q):
    """R(q / |q|), (3, 3, m) for quaternions q (4, m) (or (3, 3) for q (4,)), scalar first:
    the quadratic form over |q|^2, a rotation for any q != 0. On m points compiled
    (energy/_frames.c: the same sums point by point, one call where numpy took four)."""
    q = np.asarray(q, dtype=float)
    if q.ndim == 1:
        return (_QUADRATIC @ np.outer(q, q).reshape(16)).reshape(3, 3) / (q @ q)
    out = np.empty((3, 3, q.shape[1]))
    _frame(q, _QUADRATIC, out)
    return out


def _half_left():
    """H (4, 12): q (x) (0, u) / 2 = H @ (u (x) q), columns (k, c) for u_k q_c."""
    out = np.zeros((4, 3, 4))
    for k in range(3):
        for c in range(4):
            u, q = np.eye(3)[k], np.eye(4)[c]
            a0, a1, a2, a3 = q
            b1, b2, b3 = u
            out[:, k, c] = 0.5 * np.array((-a1 * b1 - a2 * b2 - a3 * b3,
                                           a0 * b1 + a2 * b3 - a3 * b2,
                                           a0 * b2 + a3 * b1 - a1 * b3,
                                           a0 * b3 + a1 * b2 - a2 * b1))
    out = out.reshape(4, 12)
    out.flags.writeable = False
    return out


_HALF_LEFT = _half_left()


def quaternion_rate(q, u1, u2, u3):
    """q' = q (x) (0, u) / 2, (4, m), for the quaternions q (4, m) and the body strains u (each
    (m,) or a number): H @ (u (x) q) point by point (energy/_frames.c)."""
    u = np.empty((3, q.shape[1]))
    u[0], u[1], u[2] = u1, u2, u3
    out = np.empty(q.shape)
    _quaternion_rate(q, u, _HALF_LEFT, out)
    return out


def body(R, m):
    """R^T m, (3, m): a spatial vector m (3, m) in the body frame R (3, 3, m), point by point
    (energy/_frames.c)."""
    out = np.empty(m.shape)
    _body(R, m, out)
    return out


def frame_derivatives(q, R):
    """dR/dq_j (4, 3, 3, m) of the frames R = R(q / |q|) (3, 3, m) at the quaternions q (4,
    m): 2 (D_j(q) - q_j R) / |q|^2, by one product."""
    npts = q.shape[1]
    dR = (_LINEAR @ q).reshape(4, 3, 3, npts) - q[:, None, None, :] * R[None]
    dR *= 2 / np.einsum("ij,ij->j", q, q)
    return dR


def chain(jac, R, q, m, qcols, mcols, rows_r, f_r, rows_m, f_m):
    """Add to ``jac`` (n, n, npts) the derivatives through a frame R = R(q / |q|) (3, 3,
    npts) and its body moment R^T m: for the rows ``rows_r`` with f_r = df/dR (r, 3, 3,
    npts) and the rows ``rows_m`` with f_m = df/d(R^T m) (r', 3, npts), the columns
    ``qcols`` of q and ``mcols`` of m, with dR/dq_j = 2 (D_j(q) - q_j R) / |q|^2:
    df/dq_j += f_r : dR/dq_j + f_m . (dR/dq_j)^T m and df/dm += f_m R^T. Compiled
    (energy/_frames.c: the same sums point by point, where numpy took the frames'
    derivatives, four einsums and three fancy-indexed additions, most of a spatial rod's
    Jacobian)."""
    _chain(jac, R, q, m, qcols, mcols, rows_r, f_r, rows_m, f_m, _D)


def in_rows(values, order, columns=False):
    """``values`` in the canonical order of the states (coordinates, momenta, quadratures)
    put in the module's rows: row i is the canonical state order[i]; ``columns``: the
    columns too (a Jacobian)."""
    out = np.asarray(values)[order]
    return out[:, order] if columns else out


def merged_ordinates(hand, derived) -> list:
    """The derived ordinates, each replaced by a hand-written one of the same name or the
    same ``parameter``, then the other hand-written ones (a module's own ORDINATES with
    ENERGY: `elastica_auto.energy.loader`)."""
    if not isinstance(hand, (list, tuple)):
        return hand                     # not a list: Problem says what is wrong with it
    hand = list(hand)
    used, out = set(), []
    for o in derived:
        mine = next((i for i, h in enumerate(hand) if getattr(h, "name", None) == o.name
                     or (o.parameter is not None
                         and getattr(h, "parameter", None) == o.parameter)), None)
        if mine is None:
            out.append(o)
        elif mine not in used:
            used.add(mine)
            out.append(hand[mine])
    return out + [h for i, h in enumerate(hand) if i not in used]
