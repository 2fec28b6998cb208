"""The corrector interface: everything the layers above (the stepper, the events, branch
switching, restarts, the fold-curve and symmetric problems, which are continued by the same
stepper) ask of a corrector. Nothing outside ``numerics/`` reads a corrector's discretisation,
its factorisations or its Newton iteration (``tests/test_layers.py`` checks it); they hold
:class:`~elastica_auto.numerics.correctors.Solution` values and pass them back.

A :class:`~elastica_auto.numerics.correctors.Solution` is a converged point on its mesh
(``state``, ``mesh``, ``lam``), its unit ``tangent`` oriented along the border row it was
defined with, the sign of the determinant of its bordered Jacobian ``sign`` (the
branch-point test function), its error estimate per interval ``rms`` and Newton's
``niter``; ``extra`` is the stepper's own notes (``singular``, ``contraction``). Its
linearisation ``lin`` is the corrector's, read only by the corrector.

Implemented by :class:`~elastica_auto.numerics.correctors.Collocation` (``corrector =
"collocation"``, ``ncol = 0``: the cubic scheme),
:class:`~elastica_auto.numerics.correctors.Gauss` (``corrector = "collocation"`` with
``ncol = 2..7``: Gauss collocation, its own discretisation under the collocation Newton
iteration) and :class:`~elastica_auto.numerics.correctors.SolveBVP` (``corrector =
"solve_bvp"``: every solve by scipy's solve_bvp). To add a discretisation: a subclass of
``Collocation`` whose ``discretisation(problem, s)`` gives a class with ``evaluate``,
``blocks``, ``stages``, ``weights`` and the error estimates (as ``Gauss``), chosen in
``make_corrector``; a solver: a class with these operations
(:class:`~elastica_auto.numerics.correctors.Linearizer` gives the linearisation ones for any
such discretisation), registered by name in ``CORRECTORS`` and ``core.options.CORRECTORS``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:  # annotations only
    from .correctors import FoldPoint, Resolved, Solution
    from ..core.options import ContinuationOptions
    from ..core.solution import State, Tangent


class Corrector(Protocol):
    """A corrector for continuing ``problem`` in the parameter ``parameter`` with
    ``options``. Every solve raises
    :class:`~elastica_auto.numerics.correctors.CorrectorFailure` where it does not converge.
    Meshes are node arrays on [0, 1]; a tangent or direction is a
    :class:`~elastica_auto.core.solution.Tangent` (state part and parameter part), used on any
    mesh by interpolation."""

    name: str
    problem: object
    parameter: str
    options: ContinuationOptions

    # -- solves -------------------------------------------------------------------------------
    def point(self, guess: State) -> Solution:
        """The solution at the guess's parameters from the guess, on a mesh that meets
        ``tol``, linearised with the row ``lam = value`` (a start)."""

    def at_value(self, guess: State, params: dict, value: float,
                 near: Solution | None = None) -> State:
        """The solution with the continued parameter at ``value`` (other parameters
        ``params``) from ``guess`` on its mesh; ``near``: a solution nearby the corrector may
        start from (its factorisation)."""

    def step(self, a: Solution, ds: float, curvature: Tangent | None = None) -> Solution:
        """Keller's pseudo-arclength step ``<x - a, t_a> = ds`` from ``a``, predicted at
        ``a + ds t_a`` (``+ ds^2 / 2 curvature``), on ``a``'s mesh, regridded to ``tol``."""

    def on_plane(self, a: Solution, direction: Tangent, sigma: float, s=None,
                 regrid: bool = True, curvature: Tangent | None = None) -> Solution:
        """The solution on the hyperplane ``<x - a, direction> = sigma``, started on the mesh
        ``s`` (default a's) and kept on it unless ``regrid``; linearised with the
        hyperplane's row (the trial points of every locator)."""

    def fold(self, near: Solution) -> FoldPoint:
        """The fold near ``near`` (whose tangent approximates the null vector), its solution
        and null vector resolved to ``fold_tol``."""

    # -- linearisations -----------------------------------------------------------------------
    def linearize(self, state: State, along: Tangent | None) -> Solution:
        """The converged ``state`` linearised on its mesh with the border row along ``along``
        (or ``lam = value`` where None): its tangent, oriented along that row, and the
        determinant's sign (starts, a tangent turned round, a branch point's other branch)."""

    def relinearize(self, a: Solution, s) -> Solution:
        """``a`` interpolated onto the mesh ``s`` and linearised there along its own tangent
        (to compare test functions with a point on that mesh)."""

    def determinant(self, sol: Solution, along: Tangent, s) -> tuple[int, float]:
        """(sign, log|det|) of the bordered Jacobian at ``sol`` on the mesh ``s`` with the
        border row along ``along``: the branch-point test function, smooth along a step on
        one mesh and one row."""

    def kernel(self, sol: Solution) -> tuple[Tangent, float]:
        """The unit kernel direction of the singular bordered Jacobian at the branch point
        ``sol`` (orthogonal to its border row: the other branch's direction) and its residual
        in the linearised equations relative to the size of their terms (rounding where the
        matrix is singular)."""

    def kernel_error(self, sol: Solution) -> np.ndarray:
        """The error estimate per interval of that kernel direction on ``sol``'s mesh."""

    def left_kernel(self, sol: Solution) -> np.ndarray:
        """The left kernel of the singular bordered Jacobian at the branch point ``sol``: the
        multipliers (n, m - 1) of its collocation rows, one column per interval of ``sol``'s
        mesh, which are the adjoint solution psi at the intervals' middles up to one factor
        (the row of an interval is the integral of y' - f over it)."""

    def error_estimate(self, state: State) -> np.ndarray:
        """The error estimate per interval of the solution ``state`` on its own mesh."""

    def solve_again(self, state: State, normal: Tangent | None, tol: float) -> Resolved:
        """Newton from the solution ``state`` on its own mesh, its parameter fixed or on the
        hyperplane through it normal to ``normal``: whether it solves this corrector's
        discrete equations (a stored solution checked before a restart)."""

    # -- meshes -------------------------------------------------------------------------------
    def next_mesh(self, a: Solution) -> np.ndarray:
        """The mesh the step from ``a`` starts on."""

    def fold_mesh(self, s, rms) -> np.ndarray:
        """The mesh a located point is solved again on so that it and its kernel meet
        ``fold_tol``, from the error estimate ``rms`` on ``s``."""
