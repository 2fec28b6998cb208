"""A tendon-driven continuum robot with helical routing: ``tendon_robot``'s backbone and four
tendons, each turning about the backbone k times per unit length (docs/soft-robots.md,
"Helical routing"). Tendon i runs at the body offset

    d_i(s) = delta (cos w_i, sin w_i, 0),   w_i = a_i + 2 pi k s,   a_i = (i - 1) pi / 2,

along the path r + R d_i; its unit length in the body is t_i = v + u x d_i + d_i' (the
derivative of R^T (r + R d_i), R' = R [u]_x), with d_i' = 2 pi k e3 x d_i the offset's
derivative in the body. The energy is ``tendon_robot``'s with this t_i,

    E = int_0^1 ( u.K u / 2 + (v - e3).Kse (v - e3) / 2 + sum_i tau_i |v + u x d_i + d_i'|
                  + g y ) ds + P y(1),

explicit in s through d_i(s); at k = 0 it is ``tendon_robot``'s term for term (a module of
its own so that the parallel robot's derived code keeps the exact zeros of its offsets: the
general offsets cost about 1.2x per evaluation). The momenta, balances and natural
conditions have tendon_robot's form with this t_i and d_i(1) at the tip. The ordinates, the
drawing and the straight start (exact where the tendons are slack or parallel) are
``tendon_robot``'s.
"""

from elastica_auto.energy import derived_names
from elastica_auto.equations import tendon_robot as _parallel

ANGLES = _parallel.ANGLES
ORDINATES = _parallel.ORDINATES
DRAW_PROJECTION = _parallel.DRAW_PROJECTION
draw = _parallel.draw
exact_start = _parallel.exact_start


def ENERGY():
    return _parallel.energy(helical=True)


#: Imported as a Python module, the derived names (rhs, second_variation, PARAMETERS, ...)
#: on first use; `load_problem` gives them itself.
__getattr__ = derived_names(__name__)
