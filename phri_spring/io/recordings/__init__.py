"""Lab recordings read into arrays: a comparison's experiment (manifest, trial tables) and indenter files.

- :mod:`~phri_spring.io.recordings.experiment` Experiment files for ``phri compare`` (docs/model.md section 7): manifest and trial tables
- :mod:`~phri_spring.io.recordings.indenter` Indenter recordings in, stiffness tables out (docs/model.md section 7)
"""
