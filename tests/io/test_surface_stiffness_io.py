"""The surface-stiffness cache (load_or_build) and the loader of users' FE exports."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from phri_spring.errors import DataError, UsageError
from phri_spring.io.cache import surface_stiffness as ss
from phri_spring.physics.continuum import tissue as fe_tissue
from phri_spring.physics.cuff.geometry import cuff_geometry

pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")


def small_geometry(**kw):
    """One row of four 40-degree patches on a 40 mm arm (a quick level-1 FE)."""
    args = dict(row_x=[0.0], radius=0.04, row_width=0.02, angle_start_deg=0.0,
                angle_step_deg=40.0, angle_count=4)
    args.update(kw)
    return cuff_geometry(**args)


# ----------------------------------------------------------------------- load_or_build

def test_build_then_reload_from_cache(tmp_path, monkeypatch):
    g = small_geometry()
    K, info = ss.load_or_build(g, 0.015, 2.0e4, 0.4, cache_dir=tmp_path, level=1)
    assert info["source"] == "built" and info["cache_error"] is None
    assert K.shape == (24, 24) and info["N"].shape == (4, 24)
    files = list(tmp_path.iterdir())
    assert [f.name for f in files] == [f"surface-stiffness-{info['key'][:32]}.npz"]

    def boom(*a, **k):
        raise AssertionError("the FE was rebuilt although the cache holds the matrix")

    monkeypatch.setattr(fe_tissue, "condensed_surface_operators", boom)
    K2, info2 = ss.load_or_build(g, 0.015, 5.0e4, 0.4, cache_dir=tmp_path, level=1)
    assert info2["source"] == "cache"
    # K is linear in E: the cached E = 1 matrix is scaled
    np.testing.assert_allclose(K2, K * 2.5, rtol=1e-14, atol=0)
    np.testing.assert_allclose(info2["N"], info["N"] * 2.5, rtol=1e-14, atol=0)
    assert info2["n_dofs"] == info["n_dofs"]


def test_cache_key_depends_on_everything_k_depends_on():
    g = small_geometry()
    base = ss.cache_key(g, 0.015, 0.4, level=1)
    others = [
        ss.cache_key(g, 0.016, 0.4, level=1),
        ss.cache_key(g, 0.015, 0.41, level=1),
        ss.cache_key(g, 0.015, 0.4, level=2),
        ss.cache_key(g, 0.015, 0.4, level=1, length_factor=5.0),
        ss.cache_key(g, 0.015, 0.4, level=1, ends="free"),
        ss.cache_key(small_geometry(radius=0.041), 0.015, 0.4, level=1),
        ss.cache_key(small_geometry(angle_start_deg=1.0), 0.015, 0.4, level=1),
        ss.cache_key(small_geometry(row_width=0.021), 0.015, 0.4, level=1),
    ]
    assert len({base, *others}) == len(others) + 1
    assert ss.cache_key(small_geometry(), 0.015, 0.4, level=1) == base


@pytest.mark.parametrize("garbage", [b"", b"not a zip at all", b"PK\x03\x04broken"])
def test_corrupt_cache_entry_is_rebuilt(tmp_path, garbage):
    g = small_geometry()
    key = ss.cache_key(g, 0.015, 0.4, level=1)
    path = tmp_path / f"surface-stiffness-{key[:32]}.npz"
    path.write_bytes(garbage)
    K, info = ss.load_or_build(g, 0.015, 1.0, 0.4, cache_dir=tmp_path, level=1)
    assert info["source"] == "built"
    K2, info2 = ss.load_or_build(g, 0.015, 1.0, 0.4, cache_dir=tmp_path, level=1)
    assert info2["source"] == "cache"
    np.testing.assert_array_equal(K, K2)


def test_cache_entry_of_wrong_shape_or_key_is_rebuilt(tmp_path):
    g = small_geometry()
    key = ss.cache_key(g, 0.015, 0.4, level=1)
    path = tmp_path / f"surface-stiffness-{key[:32]}.npz"
    np.savez(path, key=np.asarray(key), K=np.eye(3), N=np.zeros((1, 3)))
    _, info = ss.load_or_build(g, 0.015, 1.0, 0.4, cache_dir=tmp_path, level=1)
    assert info["source"] == "built"
    np.savez(path, key=np.asarray("someone else's key"), K=np.eye(24), N=np.zeros((4, 24)))
    K, info = ss.load_or_build(g, 0.015, 1.0, 0.4, cache_dir=tmp_path, level=1)
    assert info["source"] == "built" and not np.allclose(K, np.eye(24))


def test_unwritable_cache_folder_is_not_an_error(tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    g = small_geometry()
    K, info = ss.load_or_build(g, 0.015, 1.0, 0.4, cache_dir=blocker / "cache", level=1)
    assert info["source"] == "built" and info["cache_error"]
    assert K.shape == (24, 24)
    assert blocker.read_text() == "x"


def test_failed_build_leaves_no_file(tmp_path, monkeypatch):
    def fail(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(fe_tissue, "condensed_surface_operators", fail)
    with pytest.raises(KeyboardInterrupt):
        ss.load_or_build(small_geometry(), 0.015, 1.0, 0.4, cache_dir=tmp_path, level=1)
    assert list(tmp_path.iterdir()) == []


def test_default_cache_folder(monkeypatch, tmp_path):
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "mine"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert ss.default_cache_dir() == tmp_path / "mine"
    monkeypatch.delenv("PHRI_SPRING_CACHE")
    assert ss.default_cache_dir() == tmp_path / "xdg" / "phri-spring"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert ss.default_cache_dir() == tmp_path / "home" / ".cache" / "phri-spring"


@pytest.mark.parametrize("kw, word", [
    (dict(thickness=0.0), "thickness"), (dict(thickness=0.04), "thickness"),
    (dict(young_modulus=-1.0), "young_modulus"), (dict(poisson_ratio=0.5), "poisson_ratio"),
    (dict(young_modulus=float("nan")), "young_modulus"),
])
def test_bad_parameters_are_value_errors(tmp_path, kw, word):
    args = dict(thickness=0.015, young_modulus=1.0, poisson_ratio=0.4)
    args.update(kw)
    with pytest.raises(ValueError, match=word):
        ss.load_or_build(small_geometry(), args["thickness"], args["young_modulus"],
                         args["poisson_ratio"], cache_dir=tmp_path, level=1)
    assert list(tmp_path.iterdir()) == []


def test_missing_scikit_fem_is_one_line_naming_the_extra(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "skfem", None)   # makes `import skfem` fail
    with pytest.raises(UsageError) as err:   # parameters not built before in this process
        ss.load_or_build(small_geometry(), 0.0151, 1.0, 0.4, cache_dir=tmp_path, level=1)
    msg = str(err.value)
    assert "\n" not in msg and "pip install -e .[fe]" in msg and "scikit-fem" in msg
    with pytest.raises(UsageError):
        fe_tissue.flat_punch_stiffness(0.0201, 1.0, 0.45)


def test_importing_the_package_does_not_import_skfem():
    code = ("import sys, phri_spring, phri_spring.io.cache.surface_stiffness, "
            "phri_spring.physics.continuum.tissue; print('skfem' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


# ------------------------------------------------------------ load_surface_stiffness

def spd(m, seed=0):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(m, m))
    return a @ a.T + m * np.eye(m)


def save(path, **arrays):
    np.savez(path, **arrays)
    return path


@pytest.mark.parametrize("size", [6, 3])
def test_good_export_loads(tmp_path, size):
    g = small_geometry()
    K = spd(size * g.n) * 1e3
    K[0, 1] += 1e-13 * np.max(np.abs(K))     # within the symmetry tolerance
    p = save(tmp_path / "k.npz", K=K, labels=np.array(g.labels))
    out = ss.load_surface_stiffness(p, g)
    assert out.shape == K.shape
    np.testing.assert_allclose(out, 0.5 * (K + K.T), rtol=0, atol=0)
    np.testing.assert_array_equal(out, out.T)


def test_byte_string_labels_are_accepted(tmp_path):
    g = small_geometry()
    p = save(tmp_path / "k.npz", K=spd(3 * g.n), labels=np.array(g.labels, dtype="S"))
    assert ss.load_surface_stiffness(p, g).shape == (3 * g.n, 3 * g.n)


def _bad_cases(g):
    n = g.n
    good = spd(6 * n)
    labels = np.array(g.labels)
    nonsym = good.copy()
    nonsym[0, 1] += 1e-6 * np.max(np.abs(good))
    indefinite = good.copy()
    indefinite[0, 0] = -1.0
    nan = good.copy()
    nan[2, 2] = np.nan
    return {
        "missing K": (dict(labels=labels), "'K'"),
        "missing labels": (dict(K=good), "'labels'"),
        "wrong shape": (dict(K=spd(6 * n + 1), labels=labels), "shape"),
        "not square": (dict(K=np.ones((6 * n, 3 * n)), labels=labels), "shape"),
        "labels mismatch": (dict(K=good, labels=labels[::-1]), "labels"),
        "labels too few": (dict(K=good, labels=labels[:-1]), "labels"),
        "labels numbers": (dict(K=good, labels=np.arange(n)), "labels"),
        "not finite": (dict(K=nan, labels=labels), "NaN"),
        "text K": (dict(K=np.array(["a"] * 4), labels=labels), "numbers"),
        "not symmetric": (dict(K=nonsym, labels=labels), "not symmetric"),
        "not positive definite": (dict(K=indefinite, labels=labels), "positive definite"),
        "zero": (dict(K=np.zeros((6 * n, 6 * n)), labels=labels), "positive definite"),
    }


@pytest.mark.parametrize("case", list(_bad_cases(small_geometry())))
def test_bad_export_is_one_line_data_error(tmp_path, case):
    g = small_geometry()
    arrays, word = _bad_cases(g)[case]
    p = save(tmp_path / "bad.npz", **arrays)
    with pytest.raises(DataError) as err:
        ss.load_surface_stiffness(p, g)
    msg = str(err.value)
    assert "\n" not in msg and str(p) in msg and word in msg


def test_bad_files_are_data_errors(tmp_path):
    g = small_geometry()
    cases = {
        tmp_path / "missing.npz": None,
        tmp_path / "text.npz": b"K = 1 2 3\n",
        tmp_path / "empty.npz": b"",
        tmp_path / "broken.npz": b"PK\x03\x04 truncated zip",
    }
    for p, content in cases.items():
        if content is not None:
            p.write_bytes(content)
    npy = tmp_path / "single.npy"
    np.save(npy, spd(6 * g.n))
    cases[npy] = None
    folder = tmp_path / "folder.npz"
    folder.mkdir()
    cases[folder] = None
    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, K=spd(6 * g.n), labels=np.array(list(g.labels), dtype=object))
    cases[pickled] = None
    for p in cases:
        with pytest.raises(DataError) as err:
            ss.load_surface_stiffness(p, g)
        msg = str(err.value)
        assert "\n" not in msg and str(p) in msg, msg


def test_loader_never_modifies_the_file(tmp_path):
    g = small_geometry()
    K = spd(6 * g.n)
    p = save(tmp_path / "k.npz", K=K, labels=np.array(g.labels))
    before = p.read_bytes()
    ss.load_surface_stiffness(p, g)
    assert p.read_bytes() == before


def test_cache_entry_whose_node_rows_do_not_belong_to_its_patches_is_rebuilt(tmp_path):
    g = small_geometry()
    ops = ss.load_or_build_operators(g, 0.015, 1.0, 0.4, cache_dir=tmp_path, level=1)
    path = next(tmp_path.iterdir())
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["part_patch"] = ops.part_patch[::-1].astype(float)     # not grouped in order
    np.savez(path, **arrays)
    again = ss.load_or_build_operators(g, 0.015, 1.0, 0.4, cache_dir=tmp_path, level=1)
    assert again.info["source"] == "built"
    np.testing.assert_array_equal(again.part_patch, ops.part_patch)
