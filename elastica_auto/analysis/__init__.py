"""Layer 5, analysis: what computed branches say beyond themselves.

All equilibria at given parameters and snap-back targets (`snaps`), where a snap lands
(`landing`), stability maps between fold curves (`maps`). Imports the layers below.
"""
