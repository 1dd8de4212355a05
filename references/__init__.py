"""Reference models that validate phri_spring: not part of the installed package.

The tests (``pythonpath`` of pytest) and the benchmarks (run as modules from the
repository root, ``python -m benchmarks.NAME``) import them as ``references.X``.

- :mod:`references.contact_fe` Reference FE of the cuff's contact: rigid plates touching the tissue node by node
- :mod:`references.rigid_cuff_fe` Reference rigid-cuff FE: the checks of the condensed surface operators
"""
