"""The application layer, built on the engine core (``netsim/``): the command line, sweeps,
validation, figures, the browser replay, analysis of results and output directories.

Nothing in the core imports this package (``tests/test_layering.py``).
"""
