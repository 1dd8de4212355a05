"""The tissue's time-dependent keys of a config: ``tissue.relaxation`` and
``tissue.activation_factor`` (docs/model.md section 15)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = ["Relaxation", "ACTIVATION_FACTOR"]

#: k(a = 1) / k(a = 0) of limb tissue under a cuff: contracting the muscle roughly doubles
#: the indentation stiffness at the thigh and shank (J. Biomech. 135 (2022) 111032)
ACTIVATION_FACTOR = 2.0


class Relaxation(BaseModel):
    """``tissue.relaxation``: the Prony series G(t) = 1 - sum g_i (1 - exp(-t / tau_i))."""

    model_config = ConfigDict(extra="forbid", strict=False)

    fractions: list[float] = Field(json_schema_extra={"unit": "-"})
    times_s: list[float] = Field(json_schema_extra={"unit": "s"})

    @model_validator(mode="after")
    def _series(self):
        import math

        if len(self.fractions) != len(self.times_s):
            raise ValueError(f"expected as many fractions as times_s, got {len(self.fractions)} "
                             f"and {len(self.times_s)}")
        if any(not math.isfinite(g) or g < 0 for g in self.fractions):
            raise ValueError("fractions: expected finite numbers >= 0")
        if not sum(self.fractions) < 1.0:
            raise ValueError(f"fractions: expected a sum < 1 (the relaxed tissue keeps a "
                             f"stiffness), got {sum(self.fractions):g}")
        if any(not math.isfinite(t) or t <= 0 for t in self.times_s):
            raise ValueError("times_s: expected finite times > 0 [s]")
        return self
