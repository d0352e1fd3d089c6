"""The one registry of forward-dynamics methods: name -> the paper's name.

Everything that takes a method (the command line, run specs, sweep files, the precision study,
the reports) reads it; a module of its own so that reading it imports no kernel.
"""

PAPER_NAMES = {"rge-a": "RGE-A", "ge-n": "GE-N", "rge-n": "RGE-N"}
METHODS = tuple(PAPER_NAMES)
ELIMINATIONS = ("ge-n", "rge-n")  # the numerical O(n^3) comparators: on a formed GIM
