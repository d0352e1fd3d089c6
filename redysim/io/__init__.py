"""The file layer: models and cases in, models out.

- :mod:`redysim.io.cases`: case files (TOML) -> :class:`Case` (model, initial state, run
  settings, digest).
- :mod:`redysim.io.dh`: DH robot files (standard, modified) -> Model.
- :mod:`redysim.io.importers`: URDF (read here) and MJCF (MuJoCo's compiler) -> Model, with notes
  on every attribute honoured, announced or refused.
- :mod:`redysim.io.export`: Model -> MJCF, URDF (a round trip, or a refusal by name).
- :mod:`redysim.io.linkage_files`: linkage files (bars, points, cut joints) -> a closed mechanism.

The top layer of the core: may import every other. See ``docs/design.md``, "Layers".
"""
