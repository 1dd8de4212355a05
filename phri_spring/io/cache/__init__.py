"""Caches on disk: the coupled FE's surface stiffness and the hyperelastic reduced models.

- :mod:`~phri_spring.io.cache.hyper_reduction` The reduced hyperelastic model's identification, cached on disk (docs/model.md section 10.8)
- :mod:`~phri_spring.io.cache.surface_stiffness` The tissue's condensed surface stiffness on disk: a build cache and users' own FE exports
"""
