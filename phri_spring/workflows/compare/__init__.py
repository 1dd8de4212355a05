"""phri compare: arm models' predictions against a sensorized cuff, and their Monte Carlo bands.

- :mod:`~phri_spring.workflows.compare.bands` ``phri compare --uncertainty N``: Monte Carlo bands of the arm models' zeroed loads
- :mod:`~phri_spring.workflows.compare.run` ``phri compare`` as library calls: rigid- vs compliant-arm predictions against a sensorized cuff
"""
