"""The tip-over envelope atlas (``python -m experiments atlas``; ``docs/atlas.md``).

Independent plans over ``robot x flipper angle x slope x heading`` on a Dask cluster, stored
in a chunked Zarr store through xarray, resumable, with polar figures and the operator's
envelope. Modules: :mod:`~experiments.atlas.spec` (the section checked, the grid),
:mod:`~experiments.atlas.axes` (each axis read: values, robot variants, terrains),
:mod:`~experiments.atlas.cell` (what a cell computes; the planner adapter),
:mod:`~experiments.atlas.driver` (the Dask run), :mod:`~experiments.atlas.store` (the
Zarr store),
:mod:`~experiments.atlas.figures` (envelope, figures, summary),
:mod:`~experiments.atlas.runner`.
"""
