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
        # the physics' own checks, in one place: its message without its own key's prefix
        # (the config's error names tissue.relaxation)
        from ...errors import ModelInputError
        from ...physics.history.relaxation import Prony

        try:
            Prony(self.fractions, self.times_s)
        except ModelInputError as exc:
            text = str(exc)
            for prefix in ("relaxation: ", "relaxation."):
                text = text.removeprefix(prefix)
            raise ValueError(text) from None
        return self
