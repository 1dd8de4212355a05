"""Time at the interface: relaxation functions (QLV) and spring models solved sample by sample with relaxing tissue and muscle activation.

- :mod:`~phri_spring.physics.history.kernel` The sample-by-sample equilibrium of a spring model whose tissue has a history
- :mod:`~phri_spring.physics.history.path` Muscle activation along a loading path: the coupled arm's layer and the spring arms with friction, stiffened sample by sample
- :mod:`~phri_spring.physics.history.model` Spring models whose tissue has a history: QLV relaxation and muscle activation
- :mod:`~phri_spring.physics.history.relaxation` Reduced relaxation functions of quasi-linear viscoelastic (QLV) tissue: Prony series
"""
