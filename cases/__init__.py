"""The case files that come with redysim (TOML data, no code), installed as ``redysim.case_files``.

A package only so that an installed redysim finds them (:mod:`importlib.resources`); see
``README.md`` beside this file for every field of a case file.
"""
