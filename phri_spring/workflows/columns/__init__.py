"""Extra columns of a simulated log: shear and resultant forces, why a sample has no answer, the tolerance dose.

- :mod:`~phri_spring.workflows.columns.no_answer` The forces table's columns on samples without an answer (runs with friction)
- :mod:`~phri_spring.workflows.columns.shear` The opt-in ``--shear`` columns of ``phri simulate`` (docs/model.md section 10.6)
- :mod:`~phri_spring.workflows.columns.tolerance` The forces table's dose columns and the per-element exposure table (docs/tolerance.md)
"""
