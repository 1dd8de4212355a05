"""simulate --uncertainty: Monte Carlo draws of a config's uncertain inputs and their percentile bands.

- :mod:`~phri_spring.workflows.uncertainty.draws` The uncertain inputs of a config, their Monte Carlo draws, and what scatters for each arm
- :mod:`~phri_spring.workflows.uncertainty.run` ``phri simulate --uncertainty``: Monte Carlo over what was measured with scatter
"""
