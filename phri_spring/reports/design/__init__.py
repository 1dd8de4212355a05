"""Figures and the report of phri design.

- :mod:`~phri_spring.reports.design.figures` Figures of ``phri design``, as matplotlib ``Figure`` objects (never pyplot)
- :mod:`~phri_spring.reports.design.report` report.md of ``phri design``: the study, the best design, the Pareto table, the figures
"""
