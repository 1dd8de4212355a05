"""Refactors change no bit: the solver's outputs equal those stored before the restructure.

tests/data/stored_outputs.npz was written by tests/data/make_stored_outputs.py with the
solver as it was before its active-set loop became one kernel (issue 15): a random corpus
(meshes of 15 to 160 elements, hoop and handles straps, both arms, smooth and rough logs,
the batch solver and the single-sample `Solver`) and the bundled example through
`simulate` for both arms. Equality is exact (same machine kind, same libraries).
"""

from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).with_name("data")


@pytest.fixture(scope="module")
def current():
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_stored", DATA / "make_stored_outputs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.outputs()


def test_outputs_are_bit_identical_to_the_stored_ones(current):
    stored = np.load(DATA / "stored_outputs.npz")
    assert sorted(stored.files) == sorted(current)
    for name in stored.files:
        np.testing.assert_array_equal(current[name], stored[name], err_msg=name)
