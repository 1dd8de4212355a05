"""The tissue layer at finite strain: neo-Hookean and Ogden FE, the reduced model the coupled arm solves with, its symmetry.

- :mod:`~phri_spring.physics.hyperelastic.coupled` The coupled arm with a hyperelastic (neo-Hookean or Ogden) tissue layer, at spring speed
- :mod:`~phri_spring.physics.hyperelastic.fe` Large-deformation hyperelastic reference FE of the tissue under a rigid, bonded cuff
- :mod:`~phri_spring.physics.hyperelastic.mesh` The large-deformation FE of the tissue under a rigid, bonded cuff: mesh, material, plates
- :mod:`~phri_spring.physics.hyperelastic.punch_ogden` Large-deformation flat punch on a one-term Ogden layer: stiffening rate and its inverse
- :mod:`~phri_spring.physics.hyperelastic.reduced` The reduced neo-Hookean coupled model: the hyperelastic FE condensed onto the cuff's pose
- :mod:`~phri_spring.physics.hyperelastic.symmetry` Mirror symmetry of the reduced hyperelastic model (docs/model.md section 10.8)
"""
