"""Layer 1, core: what every other layer uses and that uses nothing of the package.

The user errors (`errors`), solutions and directions on a mesh (`solution`), safe arithmetic
for numbers in run files (`expressions`), continuation options (`options`), Ctrl-C held
off around a save (`interrupts`) and where the names of the flat layout's modules live now
(`moved`). Nothing here imports from the rest of the package.
"""
