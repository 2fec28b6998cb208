"""Layer 2, model: the problem a continuation solves, as the engine sees an equation module.

The equation-module protocol (`problem`), the second variation a module returns
(`second_variation`), integral conditions and free parameters as extra states (`augmented`),
continuous symmetry with a phase condition (`symmetry`). Imports only `core`.
"""
