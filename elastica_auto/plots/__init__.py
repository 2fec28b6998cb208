"""Figures, drawn from branch files only (nothing is recomputed here).

Generic, for any equation module: `diagram` (``elastica-auto plot``), `layout` (diagrams with
configurations drawn by the module's ``draw`` hook) and `style` (the one look of all of them).
The paper's figures, which know the elastica, are `paper` (``python -m elastica_auto.plots``).
"""

from .diagram import bifurcation_diagram

__all__ = ["bifurcation_diagram"]
