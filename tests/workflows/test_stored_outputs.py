"""Refactors change no result: the solver's outputs equal those stored before the restructure.

tests/data/stored_outputs.npz was written by tests/data/make_stored_outputs.py with the
solver as it was before its active-set loop became one kernel: a random corpus (meshes
of 15 to 160 elements, hoop and handles straps, both arms, smooth and rough logs, the
batch solver and the single-sample `Solver`) and the bundled example through `simulate`
for both arms.

The stored file was written on one machine; this test runs on any. numpy and OpenBLAS
pick their SIMD kernels by CPU, so the same code on another CPU kind rounds differently
in the last bit or two (seen: 7.1e-15 N on forces of about 10 N, an AMD EPYC against the
machine that stored them). Bit equality across CPUs is therefore not promised: floating
outputs are compared to 1e-12 of their largest magnitude, a thousand times above that
round-off and far below any change a real edit of the model or the solver makes (the
smallest such change seen, a one-ulp change of one stiffness, moves forces by ~1e-16
relative, but any change of method, tolerance or contact set moves them by > 1e-9).
Iteration counts are integers decided by sign tests with a relative tolerance of 1e-12;
round-off can flip such a decision only for a sample whose contact sits on the boundary
to 1e-12, so they must agree except, at most, one solve in a handful of samples.
"""

from support.helpers import TESTS  # noqa: E402

import numpy as np
import pytest

DATA = TESTS / "data"

#: tolerance relative to the largest magnitude of each stored array
RTOL_OF_PEAK = 1e-12


@pytest.fixture(scope="module")
def current():
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_stored", DATA / "make_stored_outputs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.outputs()


def assert_same_outputs(current: dict, stored) -> None:
    """Every stored array equals the current one: floats to 1e-12 of their peak, counts exactly
    but for at most 0.1 % of samples that differ by one solve."""
    assert sorted(stored.files) == sorted(current)
    for name in stored.files:
        want, got = stored[name], np.asarray(current[name])
        assert got.shape == want.shape, name
        if np.issubdtype(want.dtype, np.integer):
            diff = np.abs(got.astype(np.int64) - want.astype(np.int64))
            assert diff.max(initial=0) <= 1, name
            assert np.count_nonzero(diff) <= max(1, want.size // 1000), name
            continue
        np.testing.assert_array_equal(np.isnan(got), np.isnan(want), err_msg=name)
        peak = np.nanmax(np.abs(want)) if np.isfinite(want).any() else 0.0
        np.testing.assert_allclose(got, want, rtol=0, atol=RTOL_OF_PEAK * max(peak, 1e-300),
                                   equal_nan=True, err_msg=name)


def test_outputs_equal_the_stored_ones_to_round_off(current):
    assert_same_outputs(current, np.load(DATA / "stored_outputs.npz"))


class _Stored(dict):
    """A dict that looks like an ``np.load`` result (``.files``)."""

    @property
    def files(self):
        return list(self)


def test_the_comparison_catches_a_real_change(current):
    """The tolerance is not so loose that it would let a real change through: a relative
    change of 1e-9 in one force, a different contact set in one sample (one force moved
    by more than round-off) or two extra solves are each caught."""
    base = {k: np.array(v, copy=True) for k, v in current.items()}
    assert_same_outputs(base, _Stored(base))          # the identity passes

    moved = {k: np.array(v, copy=True) for k, v in base.items()}
    f = moved["case0_forces"]
    i = np.unravel_index(np.nanargmax(np.abs(f)), f.shape)
    f[i] *= 1 + 1e-9
    with pytest.raises(AssertionError):
        assert_same_outputs(moved, _Stored(base))

    more = {k: np.array(v, copy=True) for k, v in base.items()}
    more["case1_iterations"][3] += 2
    with pytest.raises(AssertionError):
        assert_same_outputs(more, _Stored(base))
