"""The tip-over envelope atlas (``mmstab atlas``; ``docs/atlas.md``).

Independent plans over ``robot x flipper angle x slope x heading`` on a Dask cluster, stored
in a chunked Zarr store through xarray, resumable, with polar figures and the operator's
envelope. Modules: :mod:`~mmstab.experiments.atlas.spec` (the section checked, the grid),
:mod:`~mmstab.experiments.atlas.axes` (each axis read: values, robot variants, terrains),
:mod:`~mmstab.experiments.atlas.cell` (what a cell computes; the planner adapter),
:mod:`~mmstab.experiments.atlas.driver` (the Dask run), :mod:`~mmstab.experiments.atlas.store` (the
Zarr store),
:mod:`~mmstab.experiments.atlas.figures` (envelope, figures, summary),
:mod:`~mmstab.experiments.atlas.runner`.
"""
