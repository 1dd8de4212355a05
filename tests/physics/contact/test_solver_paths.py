"""The optimised batch solver gives the results of the plain per-sample path (docs/performance.md).

`solve` (vectorised, cached factorisations, warm start, dense Cholesky for
fine meshes, chunked blocks) must agree with `solve_per_sample` (one sample at
a time, np.linalg.solve in an active-set loop) on random logs, and the
streaming command must agree with the in-memory call.
"""

import numpy as np
import pandas as pd
import pytest

from phri_spring.physics.contact import solver as sv
from phri_spring.physics.cuff.geometry import cuff_geometry
from phri_spring.physics.springs.model import build_model, tissue_element_stiffness
from phri_spring.synthetic.wrench import smooth_random_log


def _model(rows, angles, span=245.0, strap="hoop", arm="compliant", seed=0):
    rng = np.random.default_rng(seed)
    step = span / angles
    g = cuff_geometry(np.linspace(-0.025, 0.025, rows), 0.045, 0.075 / rows, 57.5 + step / 2,
                      step, angles)
    k_t = tissue_element_stiffness(rng.uniform(3500, 5000, g.n), g.areas)
    k_c = rng.uniform(3e4, 1e6, g.n)
    return build_model(g, k_t, k_c, arm=arm, strap_model=strap)


def _logs(n, seed):
    _, smooth = smooth_random_log(n, seed=seed)
    rng = np.random.default_rng(seed)
    rough = rng.normal(size=(n, 6)) * np.array([150, 150, 150, 6, 6, 6])
    return smooth, rough


@pytest.mark.parametrize("rows,angles", [(3, 7), (2, 5), (6, 24), (10, 36)])
@pytest.mark.parametrize("strap", ["hoop", "handles"])
def test_batch_equals_per_sample(rows, angles, strap):
    model = _model(rows, angles, strap=strap, seed=rows * angles)
    for W in _logs(600, seed=angles):
        fast = sv.solve(model, W)
        slow = sv.solve_per_sample(model, W)
        assert fast.converged.all() and slow.converged.all()
        np.testing.assert_allclose(fast.forces, slow.forces, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(fast.contact, slow.contact)
        np.testing.assert_allclose(fast.u, slow.u, rtol=0, atol=1e-12)


def test_blocks_warm_start_and_order_do_not_change_results(monkeypatch):
    model = _model(3, 7, seed=3)
    _, W = smooth_random_log(5000, seed=5)
    ref = sv.solve(model, W, warm_start=False)
    monkeypatch.setattr(sv, "_BLOCK_ENTRIES", 21 * 300)  # many small blocks
    for kwargs in ({}, {"warm_start": True}, {"initial_active": np.zeros(model.n, bool)}):
        res = sv.solve(model, W, **kwargs)
        np.testing.assert_allclose(res.forces, ref.forces, rtol=0, atol=1e-9)
    perm = np.random.default_rng(0).permutation(len(W))
    res = sv.solve(model, W[perm])
    np.testing.assert_allclose(res.forces, ref.forces[perm], rtol=0, atol=1e-9)


def test_single_sample_solver_matches_batch():
    model = _model(3, 7, seed=9)
    smooth, rough = _logs(400, seed=2)
    solver = sv.Solver(model)
    for W in (smooth, rough):
        batch = sv.solve(model, W)
        one = np.array([solver.forces(w) for w in W])
        np.testing.assert_allclose(one, batch.forces, rtol=0, atol=1e-9)


def test_dense_path_hash_keys_exact_check():
    # more than 64 elements: contact sets are hashed; results must still be exact
    model = _model(4, 40, span=300.0, seed=4)
    _, rough = _logs(300, seed=11)
    fast = sv.solve(model, rough)
    slow = sv.solve_per_sample(model, rough)
    np.testing.assert_allclose(fast.forces, slow.forces, rtol=0, atol=1e-9)


def test_spd_batched_solver_matches_numpy():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(50, 6, 6))
    H = A @ np.swapaxes(A, 1, 2) + 6 * np.eye(6)
    rhs = rng.normal(size=(50, 6))
    x = sv._spd_solve_batched(np.ascontiguousarray(H.reshape(50, 36).T), rhs)
    np.testing.assert_allclose(x, np.linalg.solve(H, rhs[..., None])[..., 0], rtol=1e-12,
                               atol=1e-12)


def _csv_log(tmp_path, n: int, seed: int):
    """A smooth random wrench log written as CSV: (path, time, wrench)."""
    t, W = smooth_random_log(n, seed=seed)
    df = pd.DataFrame(W, columns=["Fx", "Fy", "Fz", "Mx", "My", "Mz"])
    df.insert(0, "time", t)
    log = tmp_path / "log.csv"
    df.to_csv(log, index=False)
    return log, t, W


def test_simulate_file_streams_like_in_memory(tmp_path):
    from phri_spring.io.config import load_config
    from phri_spring.workflows.simulate import simulate, simulate_file

    cfg = load_config("configs/harmony_upper_arm.yaml")
    log, t, W = _csv_log(tmp_path, 3000, seed=21)
    mem = simulate(cfg, W, time=t, baseline="window:1:3").to_frame()
    # CSV keeps 6 decimals by default (1 uN), -1 keeps every digit; Parquet is binary
    for ext, decimals, tol in (("csv", 6, 5.000001e-7), ("csv", -1, 1e-9), ("parquet", 6, 1e-9)):
        out = tmp_path / f"f{decimals}.{ext}"
        simulate_file(cfg, log, out, chunk_rows=700, baseline="window:1:3", decimals=decimals)
        got = pd.read_csv(out) if ext == "csv" else pd.read_parquet(out)
        assert list(got.columns) == list(mem.columns)
        np.testing.assert_allclose(got[list(cfg.labels)].to_numpy(),
                                   mem[list(cfg.labels)].to_numpy(), rtol=0, atol=tol)
        np.testing.assert_array_equal(got["time"].to_numpy(), t)
        assert (got["peak_pressure_element"].astype(str) ==
                mem["peak_pressure_element"].astype(str)).all()


@pytest.mark.parametrize("ext", ["csv", "parquet"])
def test_log_columns_in_any_order_and_integer_types(tmp_path, ext):
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    from phri_spring.io.logs import read_wrench_log

    table = pa.table({"Mz": [6.0, 0.0], "Fx": pa.array([1, 7], pa.int64()), "Fy": [2.0, 0.0],
                      "Fz": [3.0, 0.0], "Mx": [4.0, 0.0], "My": [5.0, 0.0], "time": [0.5, 0.6]})
    path = tmp_path / f"log.{ext}"
    (pacsv.write_csv if ext == "csv" else pq.write_table)(table, str(path))
    t, w = read_wrench_log(path)
    np.testing.assert_array_equal(t, [0.5, 0.6])
    np.testing.assert_array_equal(w, [[1, 2, 3, 4, 5, 6], [7, 0, 0, 0, 0, 0]])


def test_prefetch_keeps_order_and_reraises():
    from phri_spring.io.logs import prefetch

    assert list(prefetch(iter(range(50)), depth=2)) == list(range(50))

    def failing():
        yield 1
        yield 2
        raise ValueError("bad chunk 3")

    got = []
    with pytest.raises(ValueError, match="bad chunk 3"):
        for x in prefetch(failing()):
            got.append(x)
    assert got == [1, 2]
    # leaving early stops the reader thread (no hang, no error)
    for x in prefetch(iter(range(10_000)), depth=1):
        if x == 3:
            break


def test_cuff_stiffness_csv_may_hold_inf_tissue_may_not(tmp_path):
    import yaml

    from phri_spring.errors import DataError
    from phri_spring.io.config import load_config

    base = yaml.safe_load(open("configs/harmony_upper_arm.yaml"))
    labels = [f"{r}{j}" for r in "ABC" for j in range(7)]
    csv = tmp_path / "k.csv"
    csv.write_text("location,stiffness_N_per_m\n" +
                   "".join(f"{lab},{'inf' if lab == 'B5' else 2e5}\n" for lab in labels))
    base["cuff"]["stiffness"] = "k.csv"
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(base))
    cfg = load_config(tmp_path / "c.yaml")
    assert np.isinf(cfg.cuff_stiffness[labels.index("B5")])
    base["tissue"]["stiffness"] = "k.csv"
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(base))
    with pytest.raises(DataError, match="finite"):
        load_config(tmp_path / "t.yaml")


def test_out_buffer_reused_gives_the_same_forces():
    model = _model(6, 24, seed=6)
    _, W = smooth_random_log(2000, seed=13)
    ref = sv.solve(model, W)
    buf = np.full((len(W), model.n), 123.0)
    for _ in range(2):  # reuse: stale values must not leak into the result
        res = sv.solve(model, W, out=buf)
        assert res.forces is buf
        np.testing.assert_allclose(buf, ref.forces, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(res.contact, ref.forces > 0)
    with pytest.raises(ValueError, match="out"):
        sv.solve(model, W, out=np.empty((len(W), model.n + 1)))


def test_extras_with_an_unconverged_sample():
    from phri_spring.workflows.simulate import per_sample_extras

    model = _model(3, 7, seed=1)
    W = np.array([[0, 0, 30.0, 0, 0, 0], [0, 20.0, 0, 0, 0, 0]])
    sol = sv.solve(model, W)
    forces = sol.forces.copy()
    forces[1] = np.nan
    conv = np.array([True, False])
    extras, idx = per_sample_extras(model, forces, forces > 0, sol.iterations, conv)
    p0 = forces[0] / model.areas / 1000.0
    assert idx[0] == np.argmax(p0)
    np.testing.assert_allclose(extras["peak_pressure_kPa"][0], p0.max())
    assert np.isnan(extras["peak_pressure_kPa"][1])
    assert extras["contacts_in_touch"][1] == 0
    assert list(extras["converged"]) == [True, False]


def _writer_chunks(seed=3):
    rng = np.random.default_rng(seed)
    start = 0
    for size in rng.integers(1, 400, size=12):
        t = (start + np.arange(size)) / 100.0
        f = np.round(rng.uniform(-2, 40, size=(size, 3)), 3)
        f[f < 5] = 0.0
        extras = {"n_touch": np.count_nonzero(f, axis=1).astype(np.int64),
                  "peak_kPa": f.max(axis=1) / 3.0,
                  "peak_element": (np.argmax(f, axis=1), ("A0", "A1", "A2")),
                  "ok": f.max(axis=1) < 39.0}
        start += size
        yield t, f, extras


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_threaded_csv_writer_matches_sequential_writer(tmp_path, workers):
    import pyarrow as pa

    from phri_spring.io.logs import ForcesWriter

    types = {"n_touch": pa.int64(), "peak_kPa": pa.float64(),
             "peak_element": pa.dictionary(pa.int32(), pa.string()), "ok": pa.bool_()}
    outs = {}
    for threaded in (False, True):
        path = tmp_path / f"{threaded}.csv"
        with ForcesWriter(path, "csv", ["A0", "A1", "A2"], types, threaded=threaded,
                          workers=workers) as w:
            for i, (t, f, extras) in enumerate(_writer_chunks()):
                # half the chunks hand a callable, computed on a writer thread
                w.write(t, f, (lambda e=extras: e) if i % 2 else extras)
        outs[threaded] = path.read_bytes()
    assert outs[True] == outs[False]
    lines = outs[True].decode().splitlines()
    assert lines[0] == "time,A0,A1,A2,n_touch,peak_kPa,peak_element,ok"
    expected = sum(len(t) for t, _, _ in _writer_chunks())
    assert len(lines) == 1 + expected
    got = pd.read_csv(tmp_path / "True.csv")
    np.testing.assert_array_equal(got["time"], np.arange(expected) / 100.0)
    all_f = np.concatenate([f for _, f, _ in _writer_chunks()])
    np.testing.assert_array_equal(got[["A0", "A1", "A2"]].to_numpy(), all_f)


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_threaded_writer_reraises_a_worker_error(tmp_path, fmt):
    import pyarrow as pa

    from phri_spring.io.logs import ForcesWriter

    def broken():
        raise ValueError("extras failed on chunk 2")

    chunks = list(_writer_chunks())
    with pytest.raises(ValueError, match="extras failed on chunk 2"):
        with ForcesWriter(tmp_path / f"x.{fmt}", fmt, ["A0", "A1", "A2"],
                          {"ok": pa.bool_()}, workers=2) as w:
            for i, (t, f, extras) in enumerate(chunks):
                w.write(t, f, broken if i == 2 else {"ok": extras["ok"]})


def test_streamed_summary_peak_is_the_first_largest_over_all_chunks(tmp_path):
    from phri_spring.io.config import load_config
    from phri_spring.workflows.simulate import simulate, simulate_file

    cfg = load_config("configs/harmony_upper_arm.yaml")
    log, t, W = _csv_log(tmp_path, 9000, seed=5)
    mem = simulate(cfg, W, time=t)
    j = int(np.nanargmax(mem.peak_pressure_kpa))           # numpy: the first largest
    for ext in ("csv", "parquet"):
        s = simulate_file(cfg, log, tmp_path / f"f.{ext}", chunk_rows=1024)
        assert s.max_peak_pressure_kpa == pytest.approx(mem.peak_pressure_kpa[j], rel=1e-12)
        assert s.max_peak_element == cfg.labels[int(mem.peak_element[j])]
        assert s.max_pain_ratio == pytest.approx(mem.pain_ratio[j], rel=1e-12)


@pytest.mark.parametrize("arm", ["compliant", "rigid"])
def test_absurd_finite_wrenches_are_not_converged_and_warn_nothing(arm):
    # a finite wrench so large that the forces overflow is no answer: the sample
    # is reported as not converged with NaN forces, its neighbours are untouched, and no
    # RuntimeWarning escapes (the test suite turns those into errors)
    model = _model(3, 7, arm=arm, seed=1)
    W = np.zeros((6, 6))
    W[1, 0], W[2, 2], W[3, 3], W[4, 5] = 1e308, -1e308, 1e306, 1e300
    W[5, 2] = 30.0
    sol = sv.solve(model, W)
    assert sol.converged.tolist() == [True, False, False, False, False, True]
    assert np.isnan(sol.forces[1:5]).all() and np.isfinite(sol.forces[[0, 5]]).all()
    np.testing.assert_allclose(sol.forces[[0, 5]], sv.solve(model, W[[0, 5]]).forces, rtol=0,
                               atol=1e-12)
    one = sv.Solver(model)
    assert np.isnan(one.forces(W[1])).all() and not one.last_converged
    assert np.isfinite(one.forces(W[5])).all() and one.last_converged
