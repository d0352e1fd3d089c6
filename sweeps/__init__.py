"""The sweep files that come with redysim (TOML data, no code), installed as
``redysim.sweep_files``; a package only so that an installed redysim finds them
(:mod:`importlib.resources`). Each declares a set of runs for ``redysim sweep`` and
:mod:`redysim.harness.sweep`, which reads them."""
