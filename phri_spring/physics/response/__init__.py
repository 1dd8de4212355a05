"""What the interface does: its stiffness, load sweeps, comparison metrics, and how long a pressure is tolerated.

- :mod:`~phri_spring.physics.response.metrics` Error metrics of a model-versus-measurement comparison (paper section IV-B)
- :mod:`~phri_spring.physics.response.stiffness` Interface stiffness: the 6x6 tangent stiffness of the cuff on the arm
- :mod:`~phri_spring.physics.response.sweep` Load-controlled sweeps at the load cell: force-displacement curves of the cuff on the arm
- :mod:`~phri_spring.physics.response.tolerance` How long a pressure is tolerated: published pressure-time curves and the dose of a log
"""
