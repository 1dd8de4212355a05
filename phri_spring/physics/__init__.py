"""Physics layer: pure numpy/scipy functions on arrays, SI units.

No file or config access and no printing happens here. Modules:

- :mod:`~phri_spring.physics.geometry`   element geometry of a cylindrical cuff
- :mod:`~phri_spring.physics.springs`    tissue and cuff springs, series and shear stiffness
- :mod:`~phri_spring.physics.preload`    strap pretension (hoop and handles models)
- :mod:`~phri_spring.physics.loadcell`   load-cell wrench to cuff-frame wrench
- :mod:`~phri_spring.physics.model`      the assembled spring network (arrays)
- :mod:`~phri_spring.physics.tissue_laws` tissue laws (plug-ins), the series element with the cuff
- :mod:`~phri_spring.physics.spring_newton` the spring model's equilibrium with a nonlinear law
- :mod:`~phri_spring.physics.active_set` the active-set kernel every contact model solves with
- :mod:`~phri_spring.physics.solver`     the spring model's contact system, batch and single-sample solvers
- :mod:`~phri_spring.physics.coupled`    the coupled tissue model (continuum condensed onto the patches)
- :mod:`~phri_spring.physics.fe_tissue`  built-in 3D FE of the tissue layer condensed onto the patches
- :mod:`~phri_spring.physics.fe_assembly` the FE's assembly (mesh to stiffness), shared by the FE models
- :mod:`~phri_spring.physics.fe_mesh`    the FE's structured cylindrical mesh
- :mod:`~phri_spring.physics.fe_punch`   flat punch on a bonded layer (indenter stiffness to modulus)
- :mod:`~phri_spring.physics.fe_reference` direct FE of a rigid cuff (the validation reference)
- :mod:`~phri_spring.physics.stiffness`  interface stiffness at the load cell
- :mod:`~phri_spring.physics.load_sweep` load sweeps along and about the load-cell axes (interface curves)
- :mod:`~phri_spring.physics.indentation` indenter force-displacement analysis (linear fit)
- :mod:`~phri_spring.physics.indentation_exponential` the exponential-law fit of indenter curves
- :mod:`~phri_spring.physics.indentation_signal` indenter signal windows (contact, unloading branch)
- :mod:`~phri_spring.physics.indentation_qlv` the quasi-linear viscoelastic fit of indenter trials over time
- :mod:`~phri_spring.physics.indentation_qlv_window` a trial's contact window for it, identifiability
- :mod:`~phri_spring.physics.metrics`    RMSE and zeroing used by comparisons
- :mod:`~phri_spring.physics.relaxation` QLV relaxation functions (Prony series), their recursion
- :mod:`~phri_spring.physics.history`    spring models solved in time: relaxing tissue, activation
- :mod:`~phri_spring.physics.history_kernel` the sample-by-sample loop behind it (numba when installed)
"""
