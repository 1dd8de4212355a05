"""phri fit-stiffness: indenter trials to a tissue stiffness map, and the fittable laws (linear, exponential, qlv).

- :mod:`~phri_spring.workflows.fit.laws` The tissue laws ``phri fit-stiffness --law`` can fit: names and one-line descriptions
- :mod:`~phri_spring.workflows.fit.qlv` ``phri fit-stiffness --law qlv``: quasi-linear viscoelastic tissue from indenter trials
- :mod:`~phri_spring.workflows.fit.stiffness` ``phri fit-stiffness`` as a library call: indenter recordings -> stiffness map
"""
