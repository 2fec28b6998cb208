"""Where the names of the removed modules live now: the one table behind the package's old
import paths (docs/api.md, "Deprecated paths").

Until issue 23 the package was flat (``elastica_auto/problem.py``, ``store.py``, ...); it was
then split into the layers ``core``, ``model``, ``numerics``, ``branches``, ``analysis``,
``storage`` and ``execution``, and the flat modules went. A module written against the docs of
that time (``from elastica_auto.problem import Ordinate, Parameter``) keeps working: the
package's ``__init__`` answers an import of ``elastica_auto.<old>`` with a module whose names
are looked up here, each with a DeprecationWarning that names its new place.

`MOVED` was built from the history: for each removed module, every public top-level name of
its last version, the names it defined and the names of the package it imported (both were
importable from it), plus a name earlier docs imported that the last version no longer had
(``stability.nodes_and_midpoints``). Each name maps to the module that defines it now.
`REMOVED` and `REMOVED_MODULES` hold what has no new place, with the reason given instead.
Nothing here imports anything: the table is read only when an old path is imported.

One module of the flat layout outlived the split at the top: ``path`` (snap-backs along a
path in parameter space), an analysis, moved to ``analysis/path.py`` in the same version
(issue 48), its front end ``snaps_along`` to `elastica_auto.api`; it has its row here like the
others.
"""

#: The version whose import paths these are (the flat layout), and the first that warns.
OLD_VERSION = "0.1.0"
DEPRECATED_IN = "0.2.0"

#: Old module (relative to ``elastica_auto``) -> {new module: its names, space-separated}.
#: ``""`` is the package itself.
MOVED = {
    "augmented": {
        "core.errors": "ProblemError",
        "model.augmented": "NamesOfBase Augmented",
    },
    "bordered": {
        "numerics.bordered": "split_rows Structure structure Factorization factor",
    },
    "branch": {
        "core.solution": "State Tangent",
        "numerics.stability": "count",
        "branches.branch": ("PROFILE_GRID LABEL_TYPES INDEX_UNKNOWN LEADING_COLUMNS INDEX_COLUMNS "
                            "EXTRA_COLUMNS export_names column_names StoredLabel Point new_point "
                            "Branch"),
    },
    "bvp": {
        "model.problem": "Problem",
        "core.solution": "Curve State Tangent trapezoid_weights",
        "numerics.bvp": "bc_tol SolveResult solve_fixed solve_arclength solve_fold coarsen",
    },
    "cluster": {
        "core.errors": "ClusterError",
        "execution.cluster": ("CONNECT_TIMEOUT POLL SATURATION TaskProgress connect local close "
                              "run_on_cluster serve Background"),
    },
    "codim2": {
        "core.errors": "PlanError ProblemError StartError",
        "model.problem": "Ordinate Problem",
        "core.solution": "State",
        "branches.codim2": ("NORM fold_problem branch_point_problem fold_start branch_point_start "
                            "family_slope"),
    },
    "collocation": {
        "core.solution": "at_fractions trapezoid_weights",
        "numerics.collocation": "Evaluation Blocks Discretisation equidistributed_mesh",
    },
    "corrector": {
        "model.problem": "Problem",
        "core.solution": "Curve State Tangent trapezoid_weights inner secant",
        "numerics.bvp": "bc_tol SolveResult solve_fixed solve_arclength solve_fold coarsen",
    },
    "correctors": {
        "numerics.collocation": "Discretisation equidistributed_mesh",
        "numerics.gauss": "GaussDiscretisation",
        "numerics.newton": "NEWTON_TOL Linearization Row fold_newton newton",
        "core.options": "ContinuationOptions",
        "core.solution": "State Tangent inner",
        "numerics.correctors": ("STALE_NORMAL FOLD_TARGET MESH_ROUNDS CorrectorFailure Solution "
                                "Collocation FoldPoint SolveBVP CORRECTORS make_corrector"),
    },
    "errors": {
        "core.errors": ("ProblemError RunFileError StoreError PlanError ClusterError StartError "
                        "USER_ERRORS"),
    },
    "events": {
        "numerics.correctors": "CorrectorFailure FoldPoint Solution",
        "numerics.newton": "Linearization Row kernel",
        "core.solution": "State Tangent difference inner",
        "branches.events": ("UserValues crossings Step Located along locate_fold "
                            "locate_branch_point locate_index_change pair_suspected locate_value "
                            "locate_limit tangent_between"),
    },
    "expressions": {
        "core.expressions": "evaluate",
    },
    "gauss": {
        "numerics.collocation": "Blocks",
        "core.solution": "at_fractions trapezoid_weights",
        "numerics.gauss": "tableau GaussEvaluation GaussBlocks GaussDiscretisation",
    },
    "interrupts": {
        "core.interrupts": "Interruptions",
    },
    "landing": {
        "analysis.landing": ("NODES PUSH BEYOND FORCE_TOL MATCH TRANSIT_FRACTION T_MAX SETTLE "
                             "BARRIER_MARGIN FOLD_PARTNER Flow Landing land damping_sweep"),
    },
    "maps": {
        "analysis.maps": "MIN_CELLS StabilityMap regions plane_groups stability_maps",
    },
    "newton": {
        "numerics.collocation": "Blocks Discretisation",
        "core.solution": "State Tangent",
        "numerics.newton": ("NEWTON_TOL FOLD_NEWTON_TOL MAX_ITER FOLD_MAX_CORRECTION CHORD_AHEAD "
                            "ROUNDING_ULPS Row Linearization unit scaled_norm rounding_floor "
                            "NewtonResult newton FoldResult fold_newton kernel"),
    },
    "options": {
        "core.options": "CORRECTORS NCOL_RANGE MAX_STEP OptionsError ContinuationOptions",
    },
    "path": {
        "branches.branch": "StoredLabel",
        "core.errors": "PlanError",
        "model.problem": "Ordinate Parameter Problem",
        "analysis.path": "PATH PathProblem path_problem Snap",
        "api": "snaps_along",
    },
    "plan": {
        "model.augmented": "Augmented",
        "core.errors": "PlanError ProblemError",
        "branches.events": "UserValues",
        "core.expressions": "evaluate",
        "core.options": "ContinuationOptions OptionsError",
        "model.problem": "Problem",
        "branches.stepper": "Course Stops",
        "branches.kinds": "Limit",
        "core.solution": "State",
        "branches.branch": "StoredLabel",
        "execution.plan": "DIRECTIONS Switch StartLike Start BranchSpec Plan make_plan",
    },
    "problem": {
        "core.errors": "ProblemError",
        "model.second_variation": "Constraint SecondVariation",
        "model.problem": ("ENTERS RESERVED_NAMES Parameter Ordinate Problem shipped_equations "
                          "load_problem"),
    },
    "restart": {
        "branches.branch": "Branch",
        "numerics.collocation": "Discretisation",
        "numerics.correctors": "CorrectorFailure make_corrector",
        "core.errors": "StartError",
        "core.options": "ContinuationOptions",
        "core.solution": "State Tangent",
        "branches.stepper": "STATIONARY Course Origin Stops continue_branch",
        "branches.restart": "move",
    },
    "run": {
        "model.augmented": "Augmented",
        "branches.branch": "Branch",
        "numerics.correctors": "CorrectorFailure make_corrector",
        "core.errors": "USER_ERRORS RunFileError StartError",
        "core.interrupts": "Interruptions",
        "execution.plan": "BranchSpec Plan Start",
        "core.solution": "State Tangent",
        "analysis.maps": "stability_maps",
        "analysis.equilibria": "enumerate_equilibria",
        "analysis.snaps": "scans snap_targets",
        "numerics.stability": "label_stability",
        "branches.stepper": "INTERRUPTED Origin continue_branch",
        "branches.kinds": "start_point",
        "branches.switching": "switch_direction",
        "execution.run": "RunResult build_start number_labels switch_jobs execute compute",
        "execution.jobs": "Job Progress compute_branch cell",
    },
    "runfile": {
        "core.errors": "PlanError RunFileError StoreError ProblemError",
        "core.expressions": "evaluate",
        "core.options": "ContinuationOptions",
        "execution.plan": "BranchSpec Plan Start Switch make_plan",
        "model.problem": "Problem load_problem",
        "storage.store": "BranchFile",
        "branches.branch": "StoredLabel",
        "execution.runfile": "load apply_overrides",
    },
    "second_variation": {
        "core.errors": "ProblemError",
        "model.second_variation": "SYMMETRY_TOL Constraint SecondVariation as_second_variation",
    },
    "snaps": {
        "branches.branch": "PROFILE_GRID",
        "core.solution": "State",
        "numerics.stability": "index",
        "analysis.equilibria": ("SCAN_POINTS BOX_POINTS IVP_TOL PROFILE_NODES Equilibrium "
                                "refine_brackets enumerate_equilibria scan_box snap_lps "
                                "beyond_fold"),
        "analysis.snaps": "k_columns scan_key scans snap_targets",
    },
    "solution": {
        "core.solution": ("hermite at_fractions simpson trapezoid_weights Curve State Tangent "
                          "inner norm difference secant"),
    },
    "stability": {
        "core.errors": "ProblemError",
        "model.second_variation": "as_second_variation",
        "core.solution": "at_fractions",
        "numerics.stability": ("MAX_PHASE SINGULAR_ULPS Count LegendreError count index "
                               "count_form kernel_dimension index_change fold_sign fold_rule "
                               "label_stability nodes_and_midpoints"),
    },
    "stepper": {
        "branches.branch": "PROFILE_GRID Branch Point new_point",
        "numerics.correctors": "CorrectorFailure Solution make_corrector",
        "branches.events": ("Located Step UserValues crossings locate_branch_point locate_fold "
                            "locate_index_change locate_limit locate_value pair_suspected "
                            "tangent_between"),
        "numerics.newton": "Row",
        "core.options": "ContinuationOptions",
        "core.solution": "State Tangent difference inner norm secant",
        "numerics.stability": "Count count index_change kernel_dimension",
        "branches.stepper": ("RETRY_HALVINGS EASY_CONTRACTION STATIONARY RISE_NOISE "
                             "Stops start_solution INTERRUPTED Origin Course continue_branch"),
        "branches.kinds": "Limit PROBES start_point",
    },
    "store": {
        "": "FORMAT_VERSION",
        "branches.branch": ("INDEX_COLUMNS INDEX_UNKNOWN PROFILE_GRID Branch StoredLabel "
                            "column_names export_names"),
        "core.errors": "StoreError",
        "core.solution": "State Tangent",
        "storage.store": ("FORMAT Writer StoredBranch BranchFile rows same_file write_atomically "
                          "export_csv"),
    },
    "switching": {
        "numerics.correctors": "make_corrector",
        "numerics.newton": "Row kernel unit",
        "core.options": "ContinuationOptions",
        "model.problem": "Problem",
        "core.solution": "State Tangent",
        "branches.switching": "switch_direction",
    },
    "symmetry": {
        "model.augmented": "NamesOfBase",
        "core.errors": "ProblemError",
        "core.solution": "State Tangent trapezoid_weights",
        "model.symmetry": "FIXED_POINT PIVOT Symmetry Phased phased",
    },
}

#: Names of a moved module that have no new place -> why.
REMOVED = {
    "codim2": {
        "CUSP_SLOPE": "a cusp is decided by the ratio elastica_auto.branches.codim2.CUSP_RATIO "
                      "along the fold curve, which has no units (0.2.0, issue 45)",
        "ON_FAMILY": "a fold curve's branch point on the exact family is decided by the ratio "
                     "elastica_auto.branches.codim2.FAMILY_RATIO, which has no units (0.2.0)",
        "label_fold_curve": "a fold curve's cusps and branch points are labelled as the curve "
                            "is continued, by the placed kind "
                            "elastica_auto.branches.codim2.FoldCurvePoint (0.2.0, issue 48)",
    },
    "corrector": {
        "solve_tangent": "a step's tangent is the corrector's own (the tangent of "
                         "elastica_auto.numerics.newton's Linearization)",
    },
}

#: Removed modules whose names have no new place -> why.
REMOVED_MODULES = {
    "plots.config": "the engine draws no particular rod; an equation module draws its "
                    "configurations with its draw hook (docs/equation-modules.md), as "
                    "equations/elastica_lever_arm.py does",
}


def new_places(old: str) -> dict[str, str]:
    """{name: the module that defines it now} for the old module ``old`` (``"problem"``)."""
    return {name: new for new, names in MOVED.get(old, {}).items() for name in names.split()}
