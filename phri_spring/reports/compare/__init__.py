"""Figures and the report of phri compare.

- :mod:`~phri_spring.reports.compare.figures` Figures of ``phri compare`` (the paper's Figs. 7 and 8), as matplotlib ``Figure`` objects
- :mod:`~phri_spring.reports.compare.heatmap` Heat maps of ``phri compare`` (the paper's Fig. 8b), as matplotlib ``Figure`` objects
- :mod:`~phri_spring.reports.compare.report` report.md of ``phri compare``: the inputs, the method, the RMSE tables, the figure index
"""
