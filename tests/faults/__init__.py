"""Fault-injection tests of issue 13 (a package, so that its conftest and helpers keep their own names)."""
