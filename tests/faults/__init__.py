"""Fault-injection tests: hostile inputs, signals and outputs the system refuses (README, "Errors and exit codes").

A package, so that its conftest and helpers keep names of their own.
"""
