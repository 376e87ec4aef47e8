"""The tip-over envelope atlas (``mmstab atlas``; ``docs/atlas.md``).

Independent plans over ``robot x flipper angle x slope x heading`` on a Dask cluster, stored
in a chunked Zarr store through xarray, resumable, with polar figures and the operator's
envelope. Modules: :mod:`~mmstab.atlas.spec` (the section and axes),
:mod:`~mmstab.atlas.cell` (what a cell computes; the planner adapter),
:mod:`~mmstab.atlas.driver` (the Dask run), :mod:`~mmstab.atlas.store` (the Zarr store),
:mod:`~mmstab.atlas.figures` (envelope, figures, summary), :mod:`~mmstab.atlas.runner`.
"""
