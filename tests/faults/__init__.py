"""Fault-injection tests: hostile inputs, signals and outputs the system refuses (docs/cli.md, "Errors and exit codes").

A package, so that its conftest and helpers keep names of their own.
"""
