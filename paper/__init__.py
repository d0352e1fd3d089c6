"""The paper's published numbers (``published.toml``, data, no code), installed as
``redysim.paper``; a package only so that an installed redysim finds them
(:mod:`importlib.resources`)."""
