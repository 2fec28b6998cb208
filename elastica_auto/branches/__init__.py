"""Layer 4, branches: branches of solutions and how they are continued.

A branch in memory (`branch`), the pseudo-arclength walk (`stepper`), detection and location
of labelled points (`events`), branch switching (`switching`), restarts at changed parameter
values (`restart`) and two-parameter extended problems (`codim2`). Imports the layers below.
"""
