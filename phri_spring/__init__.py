"""phri-spring: distributed cuff-arm interface loads from a six-axis load cell.

The flat API (every name is imported on first use, so ``import phri_spring``
and the command line stay fast)::

    import numpy as np
    import phri_spring as ps

    cfg = ps.load_config("configs/harmony_upper_arm.yaml")
    res = ps.simulate(cfg, np.array([[0, 0, 33.4, 0, 0, 0]]))   # (m, 6) load-cell readings
    res.forces                                                   # (m, 21) [N]

The tissue law comes with the config: ``tissue.stiffening`` [1/m] in the YAML file (or
:func:`config_with` in a script) selects the exponential law F = (k0/beta)(exp(beta d) - 1)
of the compliant arm, and every function below runs it::

    stiff = ps.config_with(cfg, {"tissue.stiffening": 150.0})    # beta = 150 1/m
    ps.simulate(stiff, np.array([[0, 0, 33.4, 0, 0, 0]])).forces  # the exponential law's
    ps.model_from_config(stiff).law                              # ExponentialLaw(n=21)

- :func:`load_config`          YAML config -> :class:`~phri_spring.io.config.Config`
- :func:`config_with`          config + values at dotted paths (``tissue.stiffening``)
- :func:`simulate`             wrench array (m, 6) -> forces (m, n) [N] and per-sample extras
- :func:`simulate_file`        wrench log file -> forces file, streamed in bounded memory
- :func:`fit_stiffness`        indenter recordings -> tissue stiffness map [N/m]
- :func:`compare`              arm models' predictions (rigid, compliant, coupled) against a sensorized cuff
- :class:`Solver`              one sample per call, warm-started (control loops)
- :func:`model_from_config`    config -> :class:`~phri_spring.physics.springs.model.SpringModel`
- :func:`cuff_wrench`          load-cell readings (m, 6) -> wrench on the cuff (m, 6) [N, N*m]
- :func:`interface_stiffness`  tangent 6x6 stiffness of the interface at an equilibrium
- :class:`Prony`               a relaxation function G(t) (``tissue.relaxation``)
- :class:`HistoryModel`        a spring model solved in time: relaxing tissue, muscle activation

The deep module paths (``phri_spring.workflows.simulate.simulate`` ...) keep working.

Layers (kept apart, the folders show it):

- :mod:`phri_spring.physics`   pure numpy/scipy functions on arrays, SI units
- :mod:`phri_spring.io`        YAML configs, CSV/Parquet/lab files -> arrays and dataclasses, writers
- :mod:`phri_spring.reports`   matplotlib ``Figure`` objects and tables
- :mod:`phri_spring.workflows` what each command does, as plain function calls

The model is explained in ``docs/model.md`` of the repository.
"""

__version__ = "0.1.0"

#: flat name -> (module, attribute), imported on first access (PEP 562)
_LAZY = {
    "load_config": ("phri_spring.io.config", "load_config"),
    "config_with": ("phri_spring.workflows.design.plan", "config_with"),
    "simulate": ("phri_spring.workflows.simulate", "simulate"),
    "simulate_file": ("phri_spring.workflows.simulate", "simulate_file"),
    "fit_stiffness": ("phri_spring.workflows.fit.stiffness", "fit_stiffness"),
    "compare": ("phri_spring.workflows.compare.run", "compare"),
    "Solver": ("phri_spring.physics.contact.solver", "Solver"),
    "model_from_config": ("phri_spring.workflows.common", "model_from_config"),
    "cuff_wrench": ("phri_spring.workflows.common", "cuff_wrench"),
    "interface_stiffness": ("phri_spring.physics.response.stiffness", "interface_stiffness"),
    "HistoryModel": ("phri_spring.physics.history.model", "HistoryModel"),
    "Prony": ("phri_spring.physics.history.relaxation", "Prony"),
}

__all__ = sorted(_LAZY) + ["__version__"]


def __getattr__(name: str):
    try:
        module, attr = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'phri_spring' has no attribute {name!r}") from None
    import importlib

    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value      # later look-ups skip __getattr__
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
