"""The same study on a dask LocalCluster (2 workers) and on the default process pool.

Needs the ``dask`` extra (``pip install -e .[dask]``; the ``test`` extra includes it).
"""

from __future__ import annotations

import pandas as pd
import pytest

from support.design_study import make_study

distributed = pytest.importorskip("distributed")

from phri_spring.workflows.design.study import run_study  # noqa: E402


def test_local_cluster_and_pool_give_identical_tables(tmp_path):
    path = make_study(tmp_path / "s", n=300, batch_size=3)
    pool = run_study(path, tmp_path / "pool", workers=2, figures=False)
    dask = run_study(path, tmp_path / "dask", scheduler="local:2", figures=False)
    pd.testing.assert_frame_equal(dask.table, pool.table, check_exact=True)
    assert (tmp_path / "dask" / "designs.csv").read_bytes() == \
        (tmp_path / "pool" / "designs.csv").read_bytes()
    assert (tmp_path / "dask" / "best.yaml").read_bytes() == \
        (tmp_path / "pool" / "best.yaml").read_bytes()
