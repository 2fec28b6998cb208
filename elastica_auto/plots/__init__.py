"""Figures, drawn from branch files only (nothing is recomputed here).

Generic, for any equation module: `diagram` (``elastica-auto plot``), `layout` (diagrams with
configurations drawn by the module's ``draw`` hook) and `style` (the one look of all of them).
The paper's figures, which know the elastica, are `paper` (``python -m elastica_auto.plots``).
"""

__all__ = ["bifurcation_diagram"]


def __getattr__(name):
    # on first use: importing a submodule (the viewer, say) need not import the diagrams'
    # matplotlib
    if name == "bifurcation_diagram":
        from .diagram import bifurcation_diagram
        return bifurcation_diagram
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
