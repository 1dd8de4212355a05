"""The composition matrix (docs/composition.md): every arm x tissue law x continuum law x
interface x cuff x patch gap runs with outputs that obey the physics, or is refused in one
line naming a config key; the docs' table is the code's.

The output checks themselves are tested on forces written by hand (a negative force, a
tangential force past mu N, a force out of balance), so that a check that cannot fail
would show here.
"""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest

from support.helpers import REPO

pytest.importorskip("skfem", reason="the fe extra (scikit-fem) is part of the test extra")

from phri_spring.io.config import config_units, load_config  # noqa: E402
from phri_spring.physics.hyperelastic.coupled import CONTINUUM_LAWS  # noqa: E402
from phri_spring.physics.laws import TISSUE_LAWS  # noqa: E402
from phri_spring.workflows import composition as cm  # noqa: E402
from phri_spring.workflows.common import ARM_MODELS  # noqa: E402

DOC = REPO / "docs" / "composition.md"


@pytest.fixture(scope="module")
def outcomes():
    return [(c, cm.run_combination(c)) for c in cm.combinations()]


def test_the_matrix_is_the_product_of_the_registries():
    combos = cm.combinations()
    spring = [a for a in ARM_MODELS if a not in cm.CONTINUUM_ARMS]
    coupled = [a for a in ARM_MODELS if a in cm.CONTINUUM_ARMS]
    per_arm = (len(TISSUE_LAWS) * len(cm.INTERFACES) * len(cm.CUFFS) * len(cm.LIMBS)
               * len(cm.TISSUE_TIMES))
    assert len(combos) == per_arm * (len(spring) + len(coupled) * len(CONTINUUM_LAWS)
                                     * len(cm.PATCH_GAPS))
    assert len(set(combos)) == len(combos)
    # the spring arms carry no continuum axes; the coupled arm every pair of them
    assert all(c.continuum_law is None and c.patch_gap is None for c in combos
               if c.arm in spring)
    for arm in coupled:
        pairs = {(c.continuum_law, c.patch_gap) for c in combos if c.arm == arm}
        assert pairs == set(itertools.product(CONTINUUM_LAWS, cm.PATCH_GAPS))


def test_a_new_tissue_law_joins_the_matrix_by_itself(monkeypatch):
    before = len(cm.combinations())
    monkeypatch.setitem(TISSUE_LAWS, "another", TISSUE_LAWS["linear"])
    per_law = len(cm.INTERFACES) * len(cm.CUFFS) * len(cm.LIMBS) * len(cm.TISSUE_TIMES) * sum(
        len(CONTINUUM_LAWS) * len(cm.PATCH_GAPS) if a in cm.CONTINUUM_ARMS else 1
        for a in ARM_MODELS)
    assert len(cm.combinations()) == before + per_law


def test_every_combination_runs_or_is_refused_in_one_line_naming_a_key(outcomes):
    keys = set(config_units()) | {f"tissue.{p.key}" for law in TISSUE_LAWS.values()
                                  for p in law.parameters}
    keys |= {k.rsplit(".", 1)[0] for k in config_units()}     # a section: tissue.relaxation
    fails = [(c.cells(), oc.message) for c, oc in outcomes if oc.status == "fails"]
    assert not fails
    for comb, oc in outcomes:
        assert oc.status in ("runs", "refused"), (comb, oc)
        if oc.status == "refused":
            assert oc.key in keys, (comb, oc)
            assert oc.message.strip() and "\n" not in oc.message, (comb, oc)
    # the paper's model with every interface and cuff runs (with the paper's strap: an
    # elastic band is not the paper's, and friction refuses it)
    paper = [oc for c, oc in outcomes if c.arm == "compliant" and c.tissue_law == "linear"
             and c.tissue_time == "elastic" and c.cuff not in cm.CUFF_STRAPS]
    assert paper and all(oc.status == "runs" for oc in paper)


def test_the_docs_table_is_the_one_the_code_gives(outcomes):
    # the arms and laws of the package (a test module may have registered more)
    ours = set(cm.combinations(package_only=True))
    assert ours and ours <= {c for c, _ in outcomes}
    table = cm.markdown_table([(c, oc) for c, oc in outcomes if c in ours])
    assert cm.table_in(DOC) == table, (
        "docs/composition.md is stale: python -m phri_spring.workflows.composition "
        "--write docs/composition.md")


# --------------------------------------------------------------------------- the checks fail
@pytest.fixture(scope="module")
def a_friction_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("run")
    comb = cm.Combination("compliant", "linear", "mu 0.5", "compliant")
    oc = cm.run_combination(comb, folder)
    assert oc.status == "runs", oc
    return comb, load_config(folder / "composition.yaml"), folder / "composition_forces.csv"


#: the inward normal of element A1 of the composition's base config (a circle: theta 145 deg)
_A1_NORMAL = -np.array([0.0, np.cos(np.radians(145.0)), np.sin(np.radians(145.0))])


def _doctored(tmp_path, out, change):
    df = pd.read_csv(out)
    change(df)
    path = tmp_path / "doctored.csv"
    df.to_csv(path, index=False)
    return path


def _first_converged(df):
    return int(np.flatnonzero(df["converged"].astype(str).str.lower() == "true")[0])


def _negative(df):
    df.loc[_first_converged(df), "A2"] = -0.5


def _past_mu_n(df):
    # a tangential force along the arm (+x: the meridian of the untapered base limb) past the
    # cone, written consistently in the shear and the resultant columns
    extra = 0.6 * df["A2"] + 0.01
    df["A2_shear_axial_N"] = df["A2_shear_axial_N"] + extra
    df["A2_force_x_N"] = df["A2_force_x_N"] + extra


def _unbalanced(df):
    # a normal force 1 % larger, written consistently in the label and resultant columns
    cfg_normal = _A1_NORMAL
    extra = df["A1"] * 0.01 + 0.01
    df["A1"] = df["A1"] + extra
    for c, n in zip("xyz", cfg_normal):
        df[f"A1_force_{c}_N"] = df[f"A1_force_{c}_N"] + extra * n


def _inconsistent(df):
    df["A1"] = df["A1"] * 1.01 + 0.01


def _unflagged(df):
    df["converged"] = df["converged"].astype(object)
    df.loc[_first_converged(df), "converged"] = False


@pytest.mark.parametrize("change, needle", [(_negative, "negative normal force"),
                                            (_past_mu_n, "beyond mu N"),
                                            (_unbalanced, "out of balance"),
                                            (_inconsistent, "disagree with"),
                                            (_unflagged, "not flagged")])
def test_each_output_check_catches_a_broken_output(tmp_path, a_friction_run, change, needle):
    comb, cfg, out = a_friction_run
    assert cm.check_outputs(cfg, comb, out) is None
    msg = cm.check_outputs(cfg, comb, _doctored(tmp_path, out, change))
    assert msg is not None and needle in msg, msg
