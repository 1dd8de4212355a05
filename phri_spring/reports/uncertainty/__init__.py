"""Figures and report sections of uncertainty bands.

- :mod:`~phri_spring.reports.uncertainty.figures` Uncertainty bands of model predictions, as matplotlib ``Figure`` objects (never pyplot)
- :mod:`~phri_spring.reports.uncertainty.report` Text of the Monte Carlo outputs: a design study's uncertainty section, the summary line
"""
