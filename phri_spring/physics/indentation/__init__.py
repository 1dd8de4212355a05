"""Indenter trials to tissue parameters: the signal windows, the linear, exponential and quasi-linear viscoelastic fits.

- :mod:`~phri_spring.physics.indentation.exponential` Exponential (Fung-type) indenter law fitted to the unloading strokes (docs/fit-stiffness.md)
- :mod:`~phri_spring.physics.indentation.linear` Indenter force-displacement analysis (docs/model.md section 7; paper sections II-B and IV-A)
- :mod:`~phri_spring.physics.indentation.qlv` Quasi-linear viscoelastic (QLV) tissue fitted to indenter trials over time
- :mod:`~phri_spring.physics.indentation.qlv_window` The contact window of an indenter trial for the QLV fit, and whether relaxation is identifiable
- :mod:`~phri_spring.physics.indentation.signal` Indenter signal conditioning: zeroing, onset and stroke detection (docs/model.md section 7)
"""
