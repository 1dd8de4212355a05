"""Refactors change no bit: the solver's outputs equal those stored before the restructure.

tests/data/stored_outputs.npz was written by tests/data/make_stored_outputs.py with the
solver as it was before its active-set loop became one kernel (issue 15): a random corpus
(meshes of 15 to 160 elements, hoop and handles straps, both arms, smooth and rough logs,
the batch solver and the single-sample `Solver`) and the bundled example through
`simulate` for both arms. Equality is exact (same machine kind, same libraries) for
everything the batch path and `simulate` give, i.e. every file `phri simulate` writes.

The single-sample `Solver` now runs the batch kernel on a one-row array, so its
products are (1, 6) x (6, 6) matrix products where it used to multiply vectors; they
round differently in the last bit (measured: at most 3.6e-15 N on forces of about 10 N),
so its stored results are compared to 1e-13 N.
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
        if name.endswith("_single"):
            np.testing.assert_allclose(current[name], stored[name], rtol=0, atol=1e-13,
                                       err_msg=name)
        else:
            np.testing.assert_array_equal(current[name], stored[name], err_msg=name)
