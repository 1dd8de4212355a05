"""Physics layer: pure numpy/scipy functions on arrays, SI units.

No file or config access and no printing happens here (numba, when installed, compiles
one loop of :mod:`.history`). Folders name concepts, modules name variants:

- :mod:`~phri_spring.physics.contact` Contact: the active-set kernel, the batch and single-sample solvers, the solution, what carries the load, why a sample has no answer
- :mod:`~phri_spring.physics.continuum` The coupled arm's linear continuum: the condensed tissue layer, its built-in FE (mesh, assembly, punch) and the FE references that validate it
- :mod:`~phri_spring.physics.cuff` The cuff: element geometry on the limb, the load cell's frame, the strap's preload, sensor patches
- :mod:`~phri_spring.physics.friction` Contact that slides: Coulomb friction along the loading path (the interface's form, its states, the events, the normal response)
- :mod:`~phri_spring.physics.history` Time at the interface: relaxation functions (QLV) and spring models solved sample by sample with relaxing tissue and muscle activation
- :mod:`~phri_spring.physics.hyperelastic` The tissue layer at finite strain: neo-Hookean and Ogden FE, the reduced model the coupled arm solves with, its symmetry
- :mod:`~phri_spring.physics.indentation` Indenter trials to tissue parameters: the signal windows, the linear, exponential and quasi-linear viscoelastic fits
- :mod:`~phri_spring.physics.laws` Tissue laws: the normal force of an element's tissue for a compression, as plug-ins
- :mod:`~phri_spring.physics.limb` Limb shapes: cross-sections and taper, sections and strap handles on a 3D scan
- :mod:`~phri_spring.physics.response` What the interface does: its stiffness, load sweeps, comparison metrics, and how long a pressure is tolerated
- :mod:`~phri_spring.physics.springs` The paper's spring network: tissue and cuff springs, the assembled model, its equilibrium with a nonlinear law, its per-element outputs
"""
