"""Layer 6, storage: branch files (HDF5) written atomically and read lazily (`store`).

Imports the layers below (branches, stability maps).
"""
