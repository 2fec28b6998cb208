"""elastica-auto: AUTO-07p-style continuation of boundary value problems on s in [0, 1].

The engine continues the solutions of an equation module (see `elastica_auto.problem`) in one
named parameter with Keller pseudo-arclength steps and `scipy.integrate.solve_bvp` as corrector,
labels folds (LP), user points (UZ) and end points (EP, MX), and writes branches to HDF5.
"""

__version__ = "0.1.0"
FORMAT_VERSION = 1
