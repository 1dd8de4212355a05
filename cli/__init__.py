"""Command-line interface of phri-spring (installed as ``phri_cli``).

Thin by design: the commands parse options, call functions of the
``phri_spring`` library, and turn its typed errors into exit codes.
"""
