"""Foundations every layer may use: unit parsing, scene-table fields, the output
coordinate's units, parallel runs and the user's cache folder.

Nothing here imports from another part of the toolkit (except :mod:`servo_toolkit.errors`).

========================  ==========================================================
:mod:`.units`             unit strings -> SI floats (pint), at the scene boundary
:mod:`.unit_registry`     pint's registry, its definitions parsed once and cached per user
:mod:`.fields`            reading one scene table with key paths in every error
:mod:`.output_units`      the output coordinate shown in deg or mm
:mod:`.parallel`          many independent cases: an optional executor, a progress bar
:mod:`.cluster`           the executor of a running dask.distributed cluster (``--scheduler``)
:mod:`.user_cache`        the user's cache folder (pint's parsed definitions)
========================  ==========================================================
"""
