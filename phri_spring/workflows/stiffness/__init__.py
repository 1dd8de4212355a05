"""phri stiffness: the interface stiffness matrix and its force-displacement curves.

- :mod:`~phri_spring.workflows.stiffness.curves` ``phri stiffness --curves``: force-displacement curves of the cuff on the arm at the load cell
- :mod:`~phri_spring.workflows.stiffness.matrix` ``phri stiffness`` as a function: the interface stiffness a config describes, at its load cell
"""
