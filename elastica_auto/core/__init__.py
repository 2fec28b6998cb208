"""Layer 1, core: what every other layer uses and that uses nothing of the package.

The user errors (`errors`), solutions and directions on a mesh (`solution`), safe arithmetic
for numbers in run files (`expressions`), continuation options (`options`) and Ctrl-C held
off around a save (`interrupts`). Nothing here imports from the rest of the package.
"""
