"""Generators of synthetic data (example logs, indenter trials, experiments).

Every example file bundled in ``examples/`` is made by these functions with a
fixed seed (``examples/make_wrench_log.py``,
``examples/make_indenter_data.py``, ``examples/make_experiment.py``); they are labelled synthetic
wherever they are shown.
"""
