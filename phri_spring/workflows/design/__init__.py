"""phri design: parameter studies of a cuff over a load set (plan, objectives, resume, executors, uncertainty).

- :mod:`~phri_spring.workflows.design.executors` Where the batches of a study run: a local process pool, or a dask.distributed cluster
- :mod:`~phri_spring.workflows.design.objectives` Evaluating designs for ``phri design``: the load set, the objectives, Pareto sets
- :mod:`~phri_spring.workflows.design.plan` The plan of ``phri design``: the parameter values of every design, and their configs
- :mod:`~phri_spring.workflows.design.resume` Resuming ``phri design``: the finished batches of a study kept in ``OUTDIR/.phri-design/``
- :mod:`~phri_spring.workflows.design.study` ``phri design``: parameter studies of a cuff over a load set, with Pareto fronts
- :mod:`~phri_spring.workflows.design.uncertainty` Uncertainty of a design study's objectives at one design: Monte Carlo and Sobol indices
"""
