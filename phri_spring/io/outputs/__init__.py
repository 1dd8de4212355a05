"""Writing outputs: the forces table (CSV, Parquet) and atomic replacement of any output.

- :mod:`~phri_spring.io.outputs.atomic` Writing outputs so that a failed run leaves nothing behind and never touches an input
- :mod:`~phri_spring.io.outputs.forces` Contact forces out (docs/model.md section 7): the chunked, threaded forces-table writer
"""
