"""Initial value problems for many initial values at once: Dormand and Prince's explicit
Runge-Kutta pair of order 8 with embedded error estimators of orders 5 and 3 (DOP853).

The shooting scans (`elastica_auto.analysis.equilibria`) integrate y' = f(s, y) from hundreds of
initial values together, the columns of y (n, m); f is vectorised over them. A shared step
with the error of the worst column controlled keeps that one f call per stage, and avoids
importing ``scipy.integrate`` (about 0.4 s) for it.

The method: 12 stages, the 8th-order solution y1 = y0 + h sum_i b_i k_i, and from the same
stages two error estimates, e5 = h sum_i (b_i - bhat5_i) k_i (5th order) and e3 (3rd order),
combined as Hairer, Norsett and Wanner (Solving ODEs I, 2nd ed., section II.10, DOP853) do:

    err = |h| ||e5||^2 / sqrt(||e5||^2 + 0.01 ||e3||^2)

with ||.|| the rms over a column's n components of e / (atol + rtol max(|y0|, |y1|)); the
step is accepted if err <= 1 in every column, and the next step is h (0.9 err^(-1/8)) within
[0.2 h, 10 h] (no growth right after a rejection). The last stage is f at the new point,
reused as the first stage of the next step (first same as last): 12 f calls per step.
The coefficients are those of Hairer's published DOP853 (the Fortran code ``dop853.f``).

Values between steps (``s_eval``) are one more step from the start of the step that holds
each, with the shorter step length: all at once, in 12 calls of f, and (a shorter step of
the same method) at least as accurate as the steps taken.
"""

from __future__ import annotations

import numpy as np

from ..core.errors import NumericalFailure

C = np.array([0.0, 0.526001519587677318785587544488e-01, 0.789002279381515978178381316732e-01,
              0.118350341907227396726757197510, 0.281649658092772603273242802490,
              0.333333333333333333333333333333, 0.25, 0.307692307692307692307692307692,
              0.651282051282051282051282051282, 0.6, 0.857142857142857142857142857142,
              1.0])

#: A[i, :i]: the stage i's combination of the stages before it.
A = np.zeros((12, 12))
A[1, :1] = [5.26001519587677318785587544488e-2]
A[2, :2] = [1.97250569845378994544595329183e-2, 5.91751709536136983633785987549e-2]
A[3, :3] = [2.95875854768068491816892993775e-2, 0.0, 8.87627564304205475450678981324e-2]
A[4, :4] = [2.41365134159266685502369798665e-1, 0.0, -8.84549479328286085344864962717e-1,
            9.24834003261792003115737966543e-1]
A[5, :5] = [3.7037037037037037037037037037e-2, 0.0, 0.0, 1.70828608729473871279604482173e-1,
            1.25467687566822425016691814123e-1]
A[6, :6] = [3.7109375e-2, 0.0, 0.0, 1.70252211019544039314978060272e-1,
            6.02165389804559606850219397283e-2, -1.7578125e-2]
A[7, :7] = [3.70920001185047927108779319836e-2, 0.0, 0.0, 1.70383925712239993810214054705e-1,
            1.07262030446373284651809199168e-1, -1.53194377486244017527936158236e-2,
            8.27378916381402288758473766002e-3]
A[8, :8] = [6.24110958716075717114429577812e-1, 0.0, 0.0, -3.36089262944694129406857109825,
            -8.68219346841726006818189891453e-1, 2.75920996994467083049415600797e1,
            2.01540675504778934086186788979e1, -4.34898841810699588477366255144e1]
A[9, :9] = [4.77662536438264365890433908527e-1, 0.0, 0.0, -2.48811461997166764192642586468,
            -5.90290826836842996371446475743e-1, 2.12300514481811942347288949897e1,
            1.52792336328824235832596922938e1, -3.32882109689848629194453265587e1,
            -2.03312017085086261358222928593e-2]
A[10, :10] = [-9.3714243008598732571704021658e-1, 0.0, 0.0, 5.18637242884406370830023853209,
              1.09143734899672957818500254654, -8.14978701074692612513997267357,
              -1.85200656599969598641566180701e1, 2.27394870993505042818970056734e1,
              2.49360555267965238987089396762, -3.0467644718982195003823669022]
A[11, :11] = [2.27331014751653820792359768449, 0.0, 0.0, -1.05344954667372501984066689879e1,
              -2.00087205822486249909675718444, -1.79589318631187989172765950534e1,
              2.79488845294199600508499808837e1, -2.85899827713502369474065508674,
              -8.87285693353062954433549289258, 1.23605671757943030647266201528e1,
              6.43392746015763530355970484046e-1]

#: The 8th-order weights (b_2 = b_3 = b_4 = b_5 = 0).
B = np.array([5.42937341165687622380535766363e-2, 0.0, 0.0, 0.0, 0.0,
              4.45031289275240888144113950566, 1.89151789931450038304281599044,
              -5.8012039600105847814672114227, 3.1116436695781989440891606237e-1,
              -1.52160949662516078556178806805e-1, 2.01365400804030348374776537501e-1,
              4.47106157277725905176885569043e-2])

#: The 5th-order error estimate's weights (b - bhat5).
E5 = np.array([0.1312004499419488073250102996e-1, 0.0, 0.0, 0.0, 0.0,
               -0.1225156446376204440720569753e+1, -0.4957589496572501915214079952,
               0.1664377182454986536961530415e+1, -0.3503288487499736816886487290,
               0.3341791187130174790297318841, 0.8192320648511571246570742613e-1,
               -0.2235530786388629525884427845e-1])

#: The 3rd-order error estimate's weights (b - bhat3): bhat3 is b except at stages 1, 9, 12.
E3 = B.copy()
E3[0] -= 0.244094488188976377952755905512
E3[8] -= 0.733846688281611857341361741547
E3[11] -= 0.220588235294117647058823529412e-1

SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0


class IntegrationError(NumericalFailure):
    """The step size fell below rounding: the solution blows up or is not smooth."""


#: OpenBLAS runs a matrix-vector product of j x N on all cores once j N reaches 2304 times
#: its GEMM_MULTITHREAD_THRESHOLD (4), and its threads then spin on the cores that a second
#: process (a default run's worker) computes on: two box scans at once took 2.3x as long
#: each as one alone. `combine` keeps each product below it.
SINGLE_THREAD_GEMV = 9216


def combine(w, flat):
    """``w @ flat`` for weights w (j,) and stages flat (j, N), in blocks of columns that BLAS
    multiplies on this thread (SINGLE_THREAD_GEMV). (numpy's einsum, also on one thread,
    took 1.15x the CPU of a one-dimensional scan.)"""
    cols = max(1, SINGLE_THREAD_GEMV // len(w))
    n = flat.shape[1]
    if n <= cols:
        return w @ flat
    out = np.empty(n)
    for c in range(0, n, cols):
        np.matmul(w, flat[:, c:c + cols], out=out[c:c + cols])
    return out


def _stages(f, s, y, h, k):
    """Fill k[1:12] (k[0] = f(s, y) given) for steps of length h from (s, y); the new y.
    ``s`` and ``h`` are scalars or per-column arrays (m,)."""
    n, m = y.shape
    flat = k.reshape(12, n * m)
    for i in range(1, 12):
        dy = combine(A[i, :i], flat[:i]).reshape(n, m)
        k[i] = f(s + C[i] * h, y + h * dy)
    return y + h * combine(B, flat).reshape(n, m)


def _error(k, h, y0, y1, rtol, atol):
    """The error norm of the step in each column (m,): the combination of the 5th- and
    3rd-order estimates of the module docstring; inf where y1 is not finite."""
    n, m = y0.shape
    flat = k.reshape(12, n * m)
    scale = atol + rtol * np.maximum(np.abs(y0), np.abs(y1))
    e5 = np.sum((combine(E5, flat).reshape(n, m) / scale) ** 2, axis=0)
    e3 = np.sum((combine(E3, flat).reshape(n, m) / scale) ** 2, axis=0)
    denom = np.sqrt((e5 + 0.01 * e3) * n)
    with np.errstate(invalid="ignore", divide="ignore"):
        err = np.where(denom > 0, abs(h) * e5 / denom, 0.0)
    return np.where(np.all(np.isfinite(y1), axis=0), err, np.inf)


def _first_step(f, s0, y0, f0, span, rtol, atol):
    """An initial step (Hairer, Norsett and Wanner, II.4): h0 from the sizes of y0 and f0, and
    h1 with h1^8 max(|f0|, |f'|) = 0.01 (in the worst column); the smaller of 100 h0 and h1
    (one f call)."""
    scale = atol + rtol * np.abs(y0)

    def rms(v):
        return float(np.max(np.sqrt(np.mean((v / scale) ** 2, axis=0))))

    d0, d1 = rms(y0), rms(f0)
    # (at least 1e-6 of the span: y0 near 0 but not 0, against the tolerance, would give a
    # step of the order of rounding and 10 more steps to grow to size)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(max(h0, 1e-6 * span), span)
    d2 = rms(f(s0 + h0, y0 + h0 * f0) - f0) / h0
    h1 = (max(1e-6, h0 * 1e-3) if max(d1, d2) <= 1e-15
          else (0.01 / max(d1, d2)) ** (1 / 8))
    return min(100 * h0, h1, span)


def dop853(f, y0, s0: float = 0.0, s1: float = 1.0, rtol: float = 1e-11, atol: float = 1e-11,
           s_eval=None) -> np.ndarray:
    """Integrate y' = f(s, y) from y(s0) = y0 (n, m) to s1 > s0, all columns together (the
    module docstring); f(s, y) takes s per column (m,) and y (n, m). Returns y(s1), (n, m),
    or with ``s_eval`` (increasing, in [s0, s1]) y there, (n, m, len(s_eval))."""
    y = np.array(y0, dtype=float)
    n, m = y.shape
    k = np.empty((12, n, m))
    s = s0
    k[0] = f(np.full(m, s), y)
    h = _first_step(lambda t, z: f(np.full(m, t), z), s, y, k[0], s1 - s0, rtol, atol)
    # the steps' starts, kept only for values between them: a scan of a thousand columns
    # would otherwise hold every step's y to the end
    steps = [(s, y)] if s_eval is not None else None
    rejected = False
    while s < s1:
        if h < 10 * np.spacing(abs(s)):
            raise IntegrationError(f"step size {h:.3g} below rounding at s = {s:.6g}")
        h = min(h, s1 - s)
        y_new = _stages(f, np.full(m, s), y, h, k)
        err = float(np.max(_error(k, h, y, y_new, rtol, atol)))
        if err <= 1.0:
            s = s1 if h >= s1 - s else s + h
            y = y_new
            if steps is not None:
                steps.append((s, y))
            k[0] = f(np.full(m, s), y)    # the first stage of the next step
            factor = MAX_FACTOR if err == 0 else min(MAX_FACTOR, SAFETY * err ** -0.125)
            h *= min(factor, 1.0) if rejected else factor
            rejected = False
        else:
            h *= max(MIN_FACTOR, SAFETY * err ** -0.125) if np.isfinite(err) else MIN_FACTOR
            rejected = True
    if s_eval is None:
        return y
    return _values_at(f, steps, np.asarray(s_eval, dtype=float), n, m)


def _values_at(f, steps, s_eval, n, m) -> np.ndarray:
    """y at ``s_eval``: from the start of the step holding each node, one step of the node's
    distance, all nodes' columns together; (n, m, len(s_eval))."""
    starts = np.array([t for t, _ in steps])
    which = np.clip(np.searchsorted(starts, s_eval, side="right") - 1, 0, len(steps) - 1)
    y0 = np.stack([steps[i][1] for i in which], axis=-1)          # (n, m, nodes)
    h = np.broadcast_to(s_eval - starts[which], (m, len(s_eval))).ravel()
    t0 = np.broadcast_to(starts[which], (m, len(s_eval))).ravel()
    z0 = y0.reshape(n, -1)
    k = np.empty((12, n, z0.shape[1]))
    k[0] = f(t0, z0)
    return _stages(f, t0, z0, h, k).reshape(n, m, len(s_eval))
