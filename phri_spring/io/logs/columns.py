"""The wrench log's column names, shared by the config and the log readers.

Kept apart from :mod:`phri_spring.io.config` so that the readers need not import the
config module (which checks a run's memory through the readers' row counter).
"""

__all__ = ["LOG_COLUMNS", "LOG_GROUP_KEY", "OPTIONAL_LOG_COLUMNS", "ACTIVATION"]

#: the columns of a wrench log, in the config's ``load_cell.columns`` and the readers
LOG_COLUMNS = ("time", "Fx", "Fy", "Fz", "Mx", "My", "Mz")
#: spec name of the optional muscle activation column (0..1; docs/model.md section 15.2)
ACTIVATION = "activation"
#: optional columns a run reads when the log has them (a trailing "?" in ``wanted``)
OPTIONAL_LOG_COLUMNS = (ACTIVATION + "?",)
#: deprecated: the key under which a column map used to carry a TDMS/MAT log's group; the
#: readers take ``group=`` now and still honour the key for callers written before
#: (:func:`phri_spring.io.logs.base.take_group`)
LOG_GROUP_KEY = "@group"
