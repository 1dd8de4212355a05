"""Generators of synthetic data (example logs, indenter trials, experiments).

Every example file bundled in ``examples/`` is made by these functions with a
fixed seed (see ``examples/make_examples.py``); they are labelled synthetic
wherever they are shown.
"""
