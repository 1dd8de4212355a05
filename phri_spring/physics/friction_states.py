"""The three states of an element or patch under Coulomb contact (docs/model.md section 12.1).

Their codes live here, apart from the interface's compliance form
(:mod:`~phri_spring.physics.friction_form`), so that the modules the form builds on (the
nonlinear normal response, :mod:`~phri_spring.physics.friction_normal`) can read them
without importing the form.
"""

__all__ = ["RELEASED", "STUCK", "SLIDING"]

#: released (lifted off, carries nothing), stuck (tied within the cone), sliding (on it)
RELEASED, STUCK, SLIDING = 0, 1, 2
