"""The problem interface: what the engine asks of a problem, whoever built it.

Four kinds of problem implement it:

- the module's own problem, `elastica_auto.model.problem.Problem` (an equation module
  loaded and checked);
- the square problem with the integral conditions and free parameters carried as states,
  `elastica_auto.model.augmented.Augmented` (a run with ``free``; the fold-curve and
  branch-point systems of `elastica_auto.branches.codim2` are such problems of their
  extended modules);
- the phase-conditioned problem along a symmetry's circles,
  `elastica_auto.model.symmetry.Phased`;
- the module's problem along a straight path in parameter space,
  `elastica_auto.analysis.path.PathProblem` (a `Problem` of the module's hooks in ``t``).

`ProblemInterface` names everything the layers above read: the names (``states``,
``parameters``, ``ordinates``), the equations and their derivatives (``rhs``, ``bc`` and
their ``_jac`` and ``_dp``), the values of a point (``ordinate_values``, ``point_params``),
the starts (``exact_start``, ``guess``), and the optional hooks, each with its ``has_``
flag: ``second_variation``, ``shooting``, ``gradient_flow``, ``symmetry``,
``symmetric_values``, ``draw`` and the ``mirror``. Code outside the model layer tells no
kind from another (no ``isinstance`` on them, `tests/test_layers.py`): what differs is in
the answers, ``solved`` (the parameters solved for along with the states),
``approximate_start`` (a completed start only approximately a solution),
``module_problem`` (the module's own problem a wrapper is built on) and ``folds_of`` (the
problem whose folds a fold-curve system's solutions are) among them.

A problem built around another (`Wrapper`: `Augmented`, `Phased`) forwards every optional
hook it does not change to its ``base``, or refuses it with a reason (`Wrapper.REFUSED`),
which `refusal` gives; it never drops one silently. A refused hook reads as absent
(``has_...`` false, ``mirror`` None).
"""

from __future__ import annotations

import abc

#: The optional hooks, by the name of their ``has_`` flag (``mirror``: its value, or None).
OPTIONAL_HOOKS = ("second_variation", "shooting", "gradient_flow", "symmetry",
                  "symmetric_values", "draw", "mirror")


class ProblemInterface(abc.ABC):
    """What the engine asks of a problem (module docstring). Attributes every kind sets:

    ``source``, ``name``, ``module``, ``doc``
        where the equations come from (a shipped name or a path), for messages and files;
    ``states`` (``n`` of them), ``nbc``
        the unknown functions' names and the number of boundary conditions;
    ``parameters``, ``ordinates``, ``integral_names``
        the module's `Parameter` and `Ordinate` declarations by name, and the names of the
        integral conditions still to be carried (none once they are states);
    ``mirror``
        the reflection (``(rows, signs, Mirror)``, `Problem.mirrored`) or None.
    """

    #: The parameters solved for along with the states (free parameters carried as states):
    #: a point's values of them are read from its solution (`point_params`).
    solved: tuple[str, ...] = ()
    #: A start completed from the module's exact start or guess is only approximately a
    #: solution (running integrals by the trapezoidal rule): it is always solved from.
    approximate_start: bool = False
    #: For a fold-curve system (`elastica_auto.branches.codim2.fold_problem`): the problem
    #: whose folds its solutions are (the module's, or its square problem with free
    #: parameters), whose solved-for parameter is this one's first ``solved``; None for
    #: every other problem. The walk labels a fold curve's cusps where it is set
    #: (`elastica_auto.branches.codim2.FoldCurvePoint`).
    folds_of: ProblemInterface | None = None

    # -- names --------------------------------------------------------------------------------
    @property
    @abc.abstractmethod
    def parameter_names(self) -> list[str]:
        """The parameters' names, in the module's order."""

    @property
    @abc.abstractmethod
    def ordinate_names(self) -> list[str]:
        """The ordinates' names, in the module's order."""

    @abc.abstractmethod
    def defaults(self) -> dict[str, float]:
        """The parameters' default values."""

    @property
    @abc.abstractmethod
    def extra_conditions(self) -> int:
        """Conditions beyond one per state: the free parameters a continuation needs."""

    @abc.abstractmethod
    def with_free(self, free=None) -> ProblemInterface:
        """The problem the engine solves with the free parameters ``free``."""

    @property
    @abc.abstractmethod
    def module_problem(self) -> ProblemInterface:
        """The module's own problem this one is built on (itself for the module's), through
        every wrapper: the one whose states are the first of this one's, of which the
        module's ordinates and exact solution are functions at the parameters `point_params`
        gives. The fold-curve and branch-point systems (`elastica_auto.branches.codim2`) read
        it."""

    # -- the equations ------------------------------------------------------------------------
    @abc.abstractmethod
    def rhs(self, s, y, p):
        """y' = f(s, y; p) on the points ``s``, y of shape (n, m)."""

    @abc.abstractmethod
    def rhs_jac(self, s, y, p):
        """df/dy, (n, n, m)."""

    @abc.abstractmethod
    def rhs_dp(self, s, y, p, name):
        """df/dp[name], (n, m)."""

    @abc.abstractmethod
    def bc(self, ya, yb, p):
        """The boundary conditions g(y(0), y(1); p), (nbc,)."""

    @abc.abstractmethod
    def bc_jac(self, ya, yb, p):
        """(dg/dy(0), dg/dy(1)), each (nbc, n)."""

    @abc.abstractmethod
    def bc_dp(self, ya, yb, p, name):
        """dg/dp[name], (nbc,)."""

    # -- a point ------------------------------------------------------------------------------
    @abc.abstractmethod
    def ordinate_values(self, s, y, p, known=None) -> dict[str, float]:
        """The ordinates of the solution ``y`` on ``s``; those in ``known`` taken from it."""

    @abc.abstractmethod
    def point_params(self, params: dict, y) -> dict[str, float]:
        """The parameter values of a solution (those ``solved`` read from ``y``)."""

    @abc.abstractmethod
    def exact_start(self, s, p):
        """An exact solution on ``s`` at ``p`` (n, len(s)), or None."""

    @abc.abstractmethod
    def guess(self, s, p):
        """An approximate solution on ``s`` at ``p``, or None."""

    # -- the optional hooks (OPTIONAL_HOOKS) --------------------------------------------------
    @property
    @abc.abstractmethod
    def has_second_variation(self) -> bool: ...

    @property
    @abc.abstractmethod
    def has_shooting(self) -> bool: ...

    @property
    @abc.abstractmethod
    def has_gradient_flow(self) -> bool: ...

    @property
    @abc.abstractmethod
    def has_symmetry(self) -> bool: ...

    @property
    @abc.abstractmethod
    def has_symmetric_values(self) -> bool: ...

    @property
    @abc.abstractmethod
    def has_draw(self) -> bool: ...

    def refusal(self, hook: str) -> str | None:
        """Why this problem refuses the optional ``hook`` its module has (None: it does not;
        a module's own problem refuses none)."""
        return None


class Wrapper(ProblemInterface):
    """A problem built around another, ``self.base`` (module docstring): the names, the
    defaults and the optional hooks are the base's, but those the subclass refuses in
    `REFUSED` (hook -> why), which read as absent. A subclass that changes a hook defines it
    (and its ``has_`` flag) itself."""

    #: Optional hooks (`OPTIONAL_HOOKS`) this kind refuses, and why.
    REFUSED: dict[str, str] = {}

    def refusal(self, hook: str) -> str | None:
        if hook not in OPTIONAL_HOOKS:
            raise ValueError(f"{hook!r} is no optional hook; they are {OPTIONAL_HOOKS}")
        return self.REFUSED.get(hook)

    def _base_has(self, hook: str) -> bool:
        return self.refusal(hook) is None and getattr(self.base, f"has_{hook}")

    @property
    def parameter_names(self):
        return self.base.parameter_names

    @property
    def ordinate_names(self):
        return self.base.ordinate_names

    def defaults(self):
        return self.base.defaults()

    @property
    def module_problem(self):
        return self.base.module_problem

    @property
    def folds_of(self):
        return self.base.folds_of

    # -- the optional hooks, forwarded where not refused ---------------------------------------
    @property
    def mirror(self):
        return None if self.refusal("mirror") else self.base.mirror

    def mirrored(self, y, params: dict):
        """The base's mirror image of ``y`` and ``params`` (rows after its states kept)."""
        return self.base.mirrored(y, params)

    def mirrored_ordinates(self, ordinates: dict) -> dict:
        return self.base.mirrored_ordinates(ordinates)

    @property
    def has_second_variation(self) -> bool:
        return self._base_has("second_variation")

    @property
    def has_shooting(self) -> bool:
        return self._base_has("shooting")

    def shooting(self, p):
        return self.base.shooting(p)

    def shooting_reflection(self, p):
        return self.base.shooting_reflection(p)

    @property
    def has_gradient_flow(self) -> bool:
        return self._base_has("gradient_flow")

    def gradient_flow(self, p, nodes):
        return self.base.gradient_flow(p, nodes)

    @property
    def has_symmetry(self) -> bool:
        return self._base_has("symmetry")

    def symmetry(self, s, y, p):
        return self.base.symmetry(s, y, p)

    @property
    def has_symmetric_values(self) -> bool:
        return self._base_has("symmetric_values")

    def symmetric_values(self, name: str, lo: float, hi: float, p) -> list[float]:
        return self.base.symmetric_values(name, lo, hi, p)

    @property
    def has_draw(self) -> bool:
        return self._base_has("draw")

    def draw(self, ax, profile, params):
        """The base's drawing: a profile's rows after the module's states are its own."""
        return self.base.draw(ax, profile, params)

    @property
    def draw_projection(self):
        return self.base.draw_projection
