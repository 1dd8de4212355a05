"""The alarms of ``phri live``: a level with hysteresis and the checks of its options.

The pressure alarm (``--alarm``, ``--alarm-clear``, ``--alarm-hold``) and the dose alarm
(``--dose-alarm``) share :class:`Alarm` (docs/live.md, docs/tolerance.md).
"""

from __future__ import annotations

import math
from typing import Optional

from ..errors import UsageError

__all__ = ["Alarm", "ALARM_CLEAR_FRACTION", "ALARM_HOLD_S", "check_alarm_settings",
           "check_dose_alarm"]


#: the alarm clears below this fraction of its raise level unless told (--alarm-clear): a
#: ratio dithering by the noise of a load cell around the threshold raises it once
ALARM_CLEAR_FRACTION = 0.9
#: and not before it has been on this long [s] of stream time (--alarm-hold)
ALARM_HOLD_S = 0.5


class Alarm:
    """The alarm's state, with hysteresis: raised when the ratio reaches ``threshold``;
    cleared when it is below ``clear`` once the alarm has been on ``hold`` seconds of the
    stream's time (a stream whose time goes back, restarted, counts as past the hold)."""

    def __init__(self, threshold: Optional[float], clear: Optional[float] = None,
                 hold: float = ALARM_HOLD_S):
        self.threshold = threshold
        self.clear = (None if threshold is None else
                      threshold * ALARM_CLEAR_FRACTION if clear is None else float(clear))
        self.hold = float(hold)
        self.on = False
        self.count = 0
        self._since = math.nan

    def update(self, ratio: float, t: float = math.nan):
        """'on', 'off' or None (no change) at the sample of time ``t`` [s]; a NaN ratio
        changes nothing."""
        if self.threshold is None or not math.isfinite(ratio):
            return None
        if not self.on and ratio >= self.threshold:
            self.on, self._since = True, t
            self.count += 1
            return "on"
        if self.on and ratio < self.clear:
            held = t - self._since
            if not held < self.hold or held < 0:      # NaN times: no hold to wait for
                self.on = False
                return "off"
        return None


def check_dose_alarm(curve, dose_alarm):
    """The curve, after checking that a dose alarm has one and a positive level."""
    if dose_alarm is None:
        return curve
    if not (math.isfinite(dose_alarm) and dose_alarm > 0):
        raise UsageError(f"expected a positive dose, got {dose_alarm!r}", key="--dose-alarm")
    if curve is None:
        raise UsageError("a dose needs a pressure-time curve: give --tolerance NAME or the "
                         "config's tolerance.curve", key="--dose-alarm")
    return curve


def check_alarm_settings(alarm, clear, hold) -> None:
    """One line naming the option for alarm settings that cannot work together."""
    if clear is not None and alarm is None:
        raise UsageError("the clear level needs a raise level; expected --alarm RATIO too",
                         key="--alarm-clear")
    if alarm is not None and not (math.isfinite(alarm) and alarm > 0):
        raise UsageError(f"expected a positive ratio, got {alarm!r}", key="--alarm")
    if clear is not None and not (0 < clear <= alarm):
        raise UsageError(f"expected a ratio > 0 and <= --alarm {alarm:g} (the alarm clears "
                         f"below the level that raised it), got {clear!r}", key="--alarm-clear")
    if not (math.isfinite(hold) and hold >= 0):
        raise UsageError(f"expected a time >= 0 [s], got {hold!r}", key="--alarm-hold")
