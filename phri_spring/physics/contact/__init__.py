"""Contact: the active-set kernel, the batch and single-sample solvers, the solution, what carries the load, why a sample has no answer.

- :mod:`~phri_spring.physics.contact.active_set` The active-set kernel: one loop that every contact model of phri-spring solves with
- :mod:`~phri_spring.physics.contact.load_path` What the load goes through: the share of the transmitted force each kind of contact carries
- :mod:`~phri_spring.physics.contact.no_equilibrium` Why a sample with friction has no answer (docs/model.md section 12.7)
- :mod:`~phri_spring.physics.contact.paths` The solve paths beside the spring kernel: nonlinear laws, models that solve their samples themselves, Coulomb friction
- :mod:`~phri_spring.physics.contact.single` The single-sample solver for control loops (:class:`Solver`), warm-started from the call before
- :mod:`~phri_spring.physics.contact.solution` The result of a solve: :class:`Solution` (docs/model.md section 9)
- :mod:`~phri_spring.physics.contact.solver` Equilibrium of the cuff on the arm in the spring model (docs/model.md sections 4 and 9)
- :mod:`~phri_spring.physics.contact.spd6` Many 6x6 symmetric positive definite systems solved at once (the spring solvers' step)
"""
