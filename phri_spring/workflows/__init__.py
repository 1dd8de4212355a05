"""Workflows: what each command does, as plain function calls on the layers below.

- :mod:`~phri_spring.workflows.columns` Extra columns of a simulated log: shear and resultant forces, why a sample has no answer, the tolerance dose
- :mod:`~phri_spring.workflows.compare` phri compare: arm models' predictions against a sensorized cuff, and their Monte Carlo bands
- :mod:`~phri_spring.workflows.design` phri design: parameter studies of a cuff over a load set (plan, objectives, resume, executors, uncertainty)
- :mod:`~phri_spring.workflows.fit` phri fit-stiffness: indenter trials to a tissue stiffness map, and the fittable laws (linear, exponential, qlv)
- :mod:`~phri_spring.workflows.plots` Plots made while a log streams: the max-pool of the whole log and the section figure's sample
- :mod:`~phri_spring.workflows.stiffness` phri stiffness: the interface stiffness matrix and its force-displacement curves
- :mod:`~phri_spring.workflows.uncertainty` simulate --uncertainty: Monte Carlo draws of a config's uncertain inputs and their percentile bands
- :mod:`~phri_spring.workflows.common` Config -> physics glue shared by the commands
- :mod:`~phri_spring.workflows.composition` The composition matrix: every arm x tissue law x continuum law x interface x cuff x
- :mod:`~phri_spring.workflows.config_paths` Editing a config mapping by dotted path (``cuff.stiffness.per_angle[5]``), for ``phri design``
- :mod:`~phri_spring.workflows.hyper_arm` Config -> the coupled arm with a hyperelastic layer (``tissue.continuum.law``
- :mod:`~phri_spring.workflows.live` ``phri live`` as library calls: the pressure map while the experiment runs (docs/live.md)
- :mod:`~phri_spring.workflows.live_alarm` The alarms of ``phri live``: a level with hysteresis and the checks of its options
- :mod:`~phri_spring.workflows.log_run` A streamed run over a wrench log: its setup (:class:`LogRun`) and its summary, added up chunk by chunk
- :mod:`~phri_spring.workflows.pipeline` The one pipeline of simulate, simulate --uncertainty and live: readings -> forces, the baseline, the extra columns and their types
- :mod:`~phri_spring.workflows.simulate` ``phri simulate`` as library calls: wrench log -> contact force of every element
- :mod:`~phri_spring.workflows.starter` ``phri init``: a starter config from a bundled preset, and the bundled example wrench log
"""
