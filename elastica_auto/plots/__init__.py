"""Figures, drawn from branch files only (nothing is recomputed here)."""

from .diagram import bifurcation_diagram

__all__ = ["bifurcation_diagram"]
