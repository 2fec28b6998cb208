"""Layer 7, execution: a plan of branches, from a run file or the API, carried out.

The validated plan (`plan`), TOML run files (`runfile`), the run in this process and beside a
cluster (`run`), Dask clusters (`cluster`). Imports the layers below.
"""
