"""The file layer: models and cases in, models out.

- :mod:`redysim.io.cases`: case files (TOML) -> :class:`Case` (model, initial state, run
  settings, digest).
- :mod:`redysim.io.dh`: DH robot files (standard, modified) -> Model.
- :mod:`redysim.io.importers`: URDF (read here) and MJCF (MuJoCo's compiler) -> Model, with notes
  on every attribute honoured, announced or refused.
- :mod:`redysim.io.export`: Model -> MJCF, URDF (a round trip, or a refusal by name).
- :mod:`redysim.io.kinds`: the file kinds, one class each in one registry: what a file is, how
  its model is read (``load_model``), what the command line says of it.
- :mod:`redysim.io.linkage_files`: linkage files (bars, points, cut joints) -> a closed mechanism.
- :mod:`redysim.io.proteins`: protein files (a sequence, a conformation) -> a backbone's Model.
- :mod:`redysim.io.scenarios`: scenarios (a model file, a state, a horizon, what to observe).

The top layer of the core: may import every other. See ``docs/design.md``, "Layers".
"""
