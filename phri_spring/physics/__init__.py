"""Physics layer: pure numpy/scipy functions on arrays, SI units.

No file or config access and no printing happens here. Modules:

- :mod:`~phri_spring.physics.geometry`   element geometry of a cylindrical cuff
- :mod:`~phri_spring.physics.springs`    tissue and cuff springs, series and shear stiffness
- :mod:`~phri_spring.physics.preload`    strap pretension (hoop and handles models)
- :mod:`~phri_spring.physics.loadcell`   load-cell wrench to cuff-frame wrench
- :mod:`~phri_spring.physics.model`      the assembled spring network (arrays)
- :mod:`~phri_spring.physics.solver`     the equilibrium solver (energy minimiser)
- :mod:`~phri_spring.physics.indentation` indenter force-displacement analysis
- :mod:`~phri_spring.physics.metrics`    RMSE and zeroing used by comparisons
"""
