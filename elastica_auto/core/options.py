"""Continuation options, validated on construction (AUTO-07p's names where they exist)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields

from . import labels
from .values import plain, real_number


#: The correctors (:mod:`elastica_auto.numerics.correctors`).
CORRECTORS = ("collocation", "solve_bvp")
#: Gauss collocation points per interval (``ncol``; 0 is the cubic scheme).
NCOL_RANGE = (2, 7)
#: The default ``ncol``: each branch's scheme chosen from its solutions, at its start and as
#: its mesh grows (`elastica_auto.numerics.correctors.choose_ncol`), recorded with the
#: branch as the integer used.
NCOL_AUTO = "auto"

#: The initial step where none is given: clipped into [ds_min, ds_max] when those exclude it
#: (``ds_max = 0.01`` alone starts with a step of 0.01).
DEFAULT_DS = 0.05
#: Largest allowed ds_max. A step is pseudo-arclength: the distance moved in (y, lam) in the
#: norm of `elastica_auto.core.solution` (the L2 norm of y plus |lam|), in the module's units. The
#: predictor is a straight line along the tangent, which a curved branch leaves within a few
#: of its own length scales: the shipped runs need ds_max <= 2, and a problem whose values are
#: in the millions wants rescaling, not steps of millions (1e300 even overflows to inf once
#: squared in the norms).
MAX_STEP = 1e3
#: The kinds of special point whose detection a run can switch off (the option ``detect``):
#: folds and branch points, AUTO-07p's ILP and ISP.
DETECTABLE = (labels.LP, labels.BP)


class OptionsError(ValueError):
    """Inconsistent continuation options."""


@dataclass(frozen=True)
class ContinuationOptions:
    """Step control, corrector accuracy and stopping rules for one branch.

    Attributes
    ----------
    ds : float
        Initial pseudo-arclength step (its sign is ignored; the direction is set per branch).
        Not given (None), it is DEFAULT_DS (0.05) clipped into ``[ds_min, ds_max]``: bounds
        given alone are obeyed, not refused for a default nobody asked for; a ``ds`` given
        outside them is an OptionsError.
    ds_min, ds_max : float
        Bounds on |ds|; ``ds_min <= |ds| <= ds_max <= MAX_STEP`` (1e3). The step halves on
        corrector failure and the branch ends with MX once it would drop below ``ds_min``.
    growth : float
        Factor applied to |ds| after a step that converged on the first mesh (>= 1).
    max_points : int
        Points per branch including the start and the labelled points (AUTO's NMX): a
        branch never has more (`elastica_auto.branches.stepper`).
    ntst : int
        Mesh intervals of the starting mesh, and the fewest a mesh is coarsened to.
    max_nodes : int
        Largest number of mesh nodes.
    tol : float
        Error tolerance for continuation points: the largest rms relative collocation
        residual on a mesh interval (solve_bvp's measure). The residual of the cubic
        collocation scales like h^3 while the error scales like h^4, so 1e-5 gives points good
        to about 1e-7 (relative) on meshes of 50-250 nodes.
        With Gauss collocation (``ncol``) it bounds an
        estimate of the largest relative error between the nodes instead (the nodes are far
        more accurate; docs/numerics.md).
    fold_tol : float
        The same tolerance for located folds and branch points, applied to the solution and
        its null vector (user and end points use ``tol``); 1e-7 puts folds within ~1e-10 of
        an independent shooting solve (tests/test_folds.py checks 1e-9).
    max_angle : float
        Largest angle (radians) between successive tangents; a larger turn rejects the step.
    corrector : str
        ``"collocation"`` (the default: Newton on the collocation equations with one banded
        LU per step and the mesh adapted between steps) or ``"solve_bvp"`` (the same
        discretisation solved by `scipy.integrate.solve_bvp`, an independent check).
    ncol : int or "auto"
        The collocation corrector's discretisation: Gauss collocation at ``ncol`` = 2..7
        points per interval (AUTO-07p's NCOL; order 2 ncol at the nodes), or 0 for
        solve_bvp's 4th-order cubic scheme. The solve_bvp corrector always uses the latter:
        it refuses a Gauss ``ncol`` (2..7) rather than compute with another scheme than the
        one asked for. ``"auto"`` (the default) chooses per branch from its start: Gauss
        collocation at ``ncol = 4`` where the cubic scheme's mesh there would have more than
        GAUSS_PAYS times the nodes of Gauss collocation's, at its start or as its mesh grows,
        else the cubic scheme; a branch from a stored label keeps the scheme that computed it, and a
        problem with a stability index (a ``second_variation`` hook) the cubic scheme
        (`numerics.correctors.choose_ncol`; docs/numerics.md). A branch records the integer
        used.
    mirror : bool
        A run that continues a start both ways, where the module's ``MIRROR`` maps the start
        to itself and the continued parameter to its negative, computes the ``+`` branch and
        takes its mirror image as the ``-`` one (`elastica_auto.branches.mirror`); False
        computes both (to compare them, say).
    detect : dict
        Which special points are looked for along a branch: ``{"LP": bool, "BP": bool}``,
        both true by default (kinds left out stay true). ``{"LP": False}`` labels no fold
        (AUTO-07p's ILP = 0), ``{"BP": False}`` no branch point (ISP = 0); the points are
        otherwise those of a run that looks for them, but where the folds or branch points
        would have been located (the steps near them are not retried for them, and the
        index is not checked against the fold rule, which reads them). Unknown kinds are an
        OptionsError.
    """

    ds: float | None = None
    ds_min: float = 1e-6
    ds_max: float = 0.5
    growth: float = 1.4
    max_points: int = 2000
    ntst: int = 50
    max_nodes: int = 5000
    tol: float = 1e-5
    fold_tol: float = 1e-7
    max_angle: float = 0.35
    corrector: str = "collocation"
    ncol: int | str = NCOL_AUTO
    mirror: bool = True
    detect: dict = field(default_factory=lambda: dict.fromkeys(DETECTABLE, True))

    def __post_init__(self):
        for f in fields(self):
            # a numpy scalar (np.int64 from np.arange) as the Python number it holds: checked
            # as one, and stored in the branch's options (JSON) as one
            object.__setattr__(self, f.name, plain(getattr(self, f.name)))
        if self.corrector not in CORRECTORS:
            raise OptionsError(f"corrector must be one of {', '.join(CORRECTORS)}, "
                               f"got {self.corrector!r}")
        if not isinstance(self.mirror, bool):
            raise OptionsError(f"mirror must be true or false, got {self.mirror!r}")
        given = self.ds is not None
        if not given:
            # the default step within the bounds given (those checked below)
            lo, hi = self.ds_min, self.ds_max
            ds = DEFAULT_DS
            if _finite_number(lo) and _finite_number(hi):
                ds = max(lo, min(DEFAULT_DS, hi))
            object.__setattr__(self, "ds", ds)
        for f in fields(self):
            if f.name in ("corrector", "mirror", "detect", "ncol"):
                continue
            v = getattr(self, f.name)
            if not real_number(v) or not math.isfinite(v):
                raise OptionsError(f"{f.name} must be a finite number, got {v!r}")
        if not given and not 0 < self.ds_min <= self.ds_max:
            raise OptionsError(f"need 0 < ds_min <= ds_max, got ds_min={self.ds_min}, "
                               f"ds_max={self.ds_max}")
        if not 0 < self.ds_min <= abs(self.ds) <= self.ds_max:
            raise OptionsError(f"need 0 < ds_min <= |ds| <= ds_max, got ds_min={self.ds_min}, "
                               f"ds={self.ds}, ds_max={self.ds_max}")
        if self.ds_max > MAX_STEP:
            raise OptionsError(f"ds_max must be <= {MAX_STEP:g}, got {self.ds_max}")
        if self.growth < 1:
            raise OptionsError(f"growth must be >= 1, got {self.growth}")
        if self.ncol != NCOL_AUTO and (
                isinstance(self.ncol, bool) or not isinstance(self.ncol, (int, float))
                or self.ncol != 0 and not NCOL_RANGE[0] <= self.ncol <= NCOL_RANGE[1]
                or int(self.ncol) != self.ncol):
            raise OptionsError(f"ncol must be \"{NCOL_AUTO}\", 0 (the cubic scheme) or an "
                               f"integer from {NCOL_RANGE[0]} to {NCOL_RANGE[1]}, "
                               f"got {self.ncol!r}")
        if self.corrector != "collocation" and self.ncol not in (0, NCOL_AUTO):
            # solve_bvp solves the cubic scheme only; a Gauss ncol would be ignored while the
            # branch recorded it and its line said "Gauss ncol K"
            raise OptionsError(f"ncol = {self.ncol} (Gauss collocation) needs corrector = "
                               f"\"collocation\"; the {self.corrector} corrector solves the "
                               f"cubic scheme only: set ncol = 0 or \"{NCOL_AUTO}\"")
        for name in ("max_points", "ntst", "max_nodes"):
            v = getattr(self, name)
            if int(v) != v or v < 2:
                raise OptionsError(f"{name} must be an integer >= 2, got {v!r}")
        if self.max_nodes <= self.ntst:
            raise OptionsError(f"max_nodes ({self.max_nodes}) must exceed ntst ({self.ntst})")
        for name in ("tol", "fold_tol"):
            if not 0 < getattr(self, name) < 1:
                raise OptionsError(f"{name} must be in (0, 1), got {getattr(self, name)}")
        if not 0 < self.max_angle < math.pi / 2:
            raise OptionsError(f"max_angle must be in (0, pi/2) radians, got {self.max_angle}")
        # every kind present, as a dict of its own (a frozen instance's field, set once here)
        object.__setattr__(self, "detect", _detect(self.detect))

    def to_dict(self) -> dict:
        return asdict(self)


def _finite_number(v) -> bool:
    return real_number(v) and math.isfinite(v)


def _detect(value) -> dict:
    """The option ``detect`` checked: a mapping of kinds of special point (DETECTABLE) to true
    or false, completed with true for the kinds it leaves out."""
    if not hasattr(value, "items"):
        raise OptionsError(f"detect must be a table of kinds such as {{LP = false}}, "
                           f"got {value!r}")
    out = dict.fromkeys(DETECTABLE, True)
    for kind, on in value.items():
        if kind not in DETECTABLE:
            raise OptionsError(f"detect: unknown kind {kind!r}; the kinds are "
                               f"{', '.join(DETECTABLE)}")
        if not isinstance(on, bool):
            raise OptionsError(f"detect.{kind} must be true or false, got {on!r}")
        out[kind] = on
    return out
