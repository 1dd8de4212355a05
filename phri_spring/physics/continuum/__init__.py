"""The coupled arm's linear continuum: the condensed tissue layer, its built-in FE (mesh, assembly, punch).

- :mod:`~phri_spring.physics.continuum.assembly` Assembly of the built-in tissue FE on its mesh (docs/model.md section 10)
- :mod:`~phri_spring.physics.continuum.coupled` The coupled tissue model: the arm as a continuum condensed onto the sensor patches
- :mod:`~phri_spring.physics.continuum.mesh` Mesh of the tissue layer for the built-in FE model (docs/model.md section 10)
- :mod:`~phri_spring.physics.continuum.punch` Flat-punch FE: indenter stiffness of a tissue layer on the bone, and its inverse
- :mod:`~phri_spring.physics.continuum.tissue` Built-in 3D finite-element model of the tissue layer (docs/model.md section 10)
"""
