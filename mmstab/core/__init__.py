"""Inputs and shared services: problem files, schema, settings, size bounds; C cache, pool.

- ``files``: YAML/JSON reading, ``ConfigError``/``MmstabError``, atomic writers.
- ``schema``, ``settings``, ``sizes``: the problem's JSON schema, the settings registry run for
  every command at load, and bounds on every size-like setting.
- ``problem``: a validated problem (robot + terrain + path + sections); it sits above the model
  and the terrain it assembles.
- ``clib`` (mmstab's own C compiled on first use), ``pool`` (a killable process pool),
  ``masks`` (runs of True in a boolean sequence).
"""
