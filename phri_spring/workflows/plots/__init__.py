"""Plots made while a log streams: the max-pool of the whole log and the section figure's sample.

- :mod:`~phri_spring.workflows.plots.maxpool` ``phri simulate --plot``: a whole log at a glance, in bounded memory
- :mod:`~phri_spring.workflows.plots.section` The section figure of a config and one sample's forces (``phri simulate --plot``'s
"""
