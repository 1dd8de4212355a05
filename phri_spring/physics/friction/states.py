"""The three states of an element or patch under Coulomb contact (docs/model.md section 12.1).

Their codes live here, apart from the interface's compliance form
(:mod:`~phri_spring.physics.friction.form`), so that the modules the form builds on (the
nonlinear normal response, :mod:`~phri_spring.physics.friction.normal`) can read them
without importing the form.
"""

from __future__ import annotations

__all__ = ["RELEASED", "STUCK", "SLIDING", "interface_mu"]

#: released (lifted off, carries nothing), stuck (tied within the cone), sliding (on it)
RELEASED, STUCK, SLIDING = 0, 1, 2


def interface_mu(model) -> float | None:
    """The Coulomb coefficient a model's interface runs with along a loading path, or None
    for bonded ties solved sample by sample (the spring model without
    ``friction_coefficient``, the hyperelastic coupled arms). The linear coupled arm always
    has one: its ``friction_coefficient``, else the lift-off cone's (docs/model.md 10.2)."""
    mu = getattr(model, "interface_mu", None)
    return getattr(model, "friction_coefficient", None) if mu is None else mu
