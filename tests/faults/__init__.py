"""Fault-injection tests of issue 13.

A package, so that its conftest and helpers keep names of their own.
"""
