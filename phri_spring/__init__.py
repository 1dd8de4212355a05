"""phri-spring: distributed cuff-arm interface loads from a six-axis load cell.

Layers (kept apart, the folders show it):

- :mod:`phri_spring.physics`   pure numpy/scipy functions on arrays, SI units
- :mod:`phri_spring.io`        YAML configs, CSV/Parquet/lab files -> arrays and dataclasses, writers
- :mod:`phri_spring.reports`   matplotlib ``Figure`` objects and tables
- :mod:`phri_spring.workflows` what each command does, as plain function calls
"""

__version__ = "0.1.0"
