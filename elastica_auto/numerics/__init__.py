"""Layer 3, numerics: one solution at a time, and its stability.

The discretisation (`collocation`, `gauss`), bordered banded systems (`bordered`), Newton's
method (`newton`), solve_bvp's augmented problems (`bvp`), the two correctors behind one
interface (`correctors`) and the stability index (`stability`). Imports `core` and `model`.
"""
