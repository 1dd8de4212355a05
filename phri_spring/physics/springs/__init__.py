"""The paper's spring network: tissue and cuff springs, the assembled model, its equilibrium with a nonlinear law, its per-element outputs.

- :mod:`~phri_spring.physics.springs.model` The assembled spring network: plain arrays the solver works on
- :mod:`~phri_spring.physics.springs.newton` Equilibrium of the spring model with a nonlinear tissue law: damped Newton on a convex energy
- :mod:`~phri_spring.physics.springs.outputs` The spring model's outputs at a cuff displacement: compression, forces, energy (docs/model.md
- :mod:`~phri_spring.physics.springs.stiffness` Springs of the interface (docs/model.md section 2)
"""
