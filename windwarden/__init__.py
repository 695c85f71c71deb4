"""windwarden application layer: the command line, batch evaluation and the live orchestration.

This is the top of the dependency graph: it may import every other package; nothing imports it.
"""

__version__ = "0.1.0"
