"""Indenter analysis (phri_spring.physics.indentation.linear) and its synthetic generator.

Expected values are closed forms of hand-built trials (piecewise-linear depth,
force laws written out in the test), never the package's own output.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from phri_spring.physics.indentation.linear import (TrialError, default_onset_threshold,
                                             detect_onset, fit_line, fit_location, fit_trial,
                                             location_statistics, split_strokes,
                                             trial_spread, turning_points, zero_level)
from phri_spring.synthetic.indenter import (ENCODER_STEP, synth_dataset, synth_trial,
                                            truth_map)

MM = 1e-3


def profile(knots, rate):
    """Sample a piecewise-linear depth profile: knots = [(time [s], depth [m]), ...]."""
    tk, dk = np.array(knots, dtype=float).T
    n = int(round(tk[-1] * rate)) + 1
    t = np.arange(n) / rate
    return t, np.interp(t, tk, dk)


def hysteretic_force(t, d, pushes):
    """Force of the Oliver-Pharr-like law, written out per push.

    ``pushes``: list of (t_start, t_end, k_load, k_unload): while depth grows to
    its maximum dmax the force is k_load * d; afterwards k_unload * (d - r) with
    r = dmax (1 - k_load / k_unload), clipped at zero.
    """
    f = np.zeros_like(d)
    for t0, t1, kl, ku in pushes:
        m = (t >= t0) & (t < t1)
        idx = np.flatnonzero(m)
        i_peak = idx[np.argmax(d[idx])]
        dmax = d[i_peak]
        r = dmax * (1 - kl / ku)
        load = m & (t <= t[i_peak])
        unload = m & (t > t[i_peak])
        f[load] = kl * np.maximum(d[load], 0)
        f[unload] = ku * np.maximum(d[unload] - r, 0)
    return f


# --------------------------------------------------------------------------- hand-built


def single_push(rate=100.0, kl=3000.0, ku=4500.0, offset=1.5, x0=12.5 * MM):
    # rest out of contact (1 mm off) until 4 s, touch at 5 s, 3 mm deep at 7 s, back at 9 s
    t, d = profile([(0, -1 * MM), (4, -1 * MM), (5, 0), (7, 3 * MM), (9, -1 * MM),
                    (10, -1 * MM)], rate)
    f = hysteretic_force(t, d, [(0, 11, kl, ku)])
    return t, x0 + d, f + offset


def test_linear_unloading_ramp_gives_its_slope_exactly():
    t, x, f = single_push(kl=3000.0, ku=4500.0)
    fit = fit_trial(t, x, f)
    assert fit.n_strokes == 1
    assert fit.stiffness == pytest.approx(4500.0, rel=1e-9)
    assert fit.unloading.r2[0] == pytest.approx(1.0, abs=1e-12)
    # zero level = offset (noiseless), threshold = the 0.05 N floor
    assert fit.zero_level == pytest.approx(1.5, abs=1e-12)
    assert fit.threshold == pytest.approx(0.05)
    assert fit.peak_force == pytest.approx(4500.0 * 2e-3, rel=1e-12)   # 9 N at 3 mm
    # unloading F = ku (d - r), r = 1 mm, with d = depth from onset + d_on (the profile's
    # depth at the onset sample): intercept = ku (d_on - r)
    d_on = x[fit.onset_index] - 12.5 * MM
    assert fit.unloading.intercept[0] == pytest.approx(4500.0 * (d_on - 1 * MM), rel=1e-9)


def test_loading_softer_than_unloading_is_not_what_is_fitted():
    t, x, f = single_push(kl=3000.0, ku=4500.0)
    fit = fit_trial(t, x, f)
    # fitting the loading part would give 3000 N/m: the result is the unloading 4500
    assert fit.loading_slope == pytest.approx(3000.0, rel=1e-9)
    assert fit.stiffness == pytest.approx(4500.0, rel=1e-9)
    assert abs(fit.stiffness - fit.loading_slope) > 1000
    # hysteresis: W_load = 1/2 kl D^2, W_unload = 1/2 kl^2/ku D^2 -> 1 - kl/ku = 1/3
    assert fit.hysteresis_ratio == pytest.approx(1 / 3, rel=2e-3)


def test_two_stroke_trial_averages_the_unloading_slopes():
    # push 1: 2 mm deep, unloading 4000 N/m; push 2: 4 mm deep, unloading 5000 N/m
    t, d = profile([(0, -1 * MM), (4, -1 * MM), (5, 0), (6, 2 * MM), (7.5, -1 * MM),
                    (8.5, -1 * MM), (9, 0), (11, 4 * MM), (12, 4 * MM), (13.5, -1 * MM),
                    (14, -1 * MM)], 200.0)
    # a hold at the top (11-12 s) belongs to neither stroke
    f = hysteretic_force(t, d, [(0, 8.5, 3600.0, 4000.0), (8.5, 15, 4500.0, 5000.0)])
    fit = fit_trial(t, -7 * MM + d, f - 0.8)
    assert fit.n_strokes == 2
    np.testing.assert_allclose(fit.unloading.slope, [4000.0, 5000.0], rtol=1e-9)
    np.testing.assert_allclose(fit.loading.slope, [3600.0, 4500.0], rtol=1e-9)
    assert fit.stiffness == pytest.approx(4500.0, rel=1e-9)
    # hysteresis per push = 1 - kl/ku
    np.testing.assert_allclose(fit.hysteresis, [0.1, 0.1], rtol=5e-3)
    # the unloading of push 2 starts at the end of the hold (last sample at 4 mm)
    assert fit.time[fit.unloading.start[1]] == pytest.approx(12.0)
    assert fit.time[fit.peak_index[1]] == pytest.approx(11.0)


def test_reversed_encoder_is_flipped():
    t, x, f = single_push()
    fit = fit_trial(t, -x, f)
    assert fit.sign == -1
    assert fit.stiffness == pytest.approx(4500.0, rel=1e-9)


def test_quantised_noisy_push_within_one_percent():
    rng = np.random.default_rng(5)
    t, x, f = single_push(rate=250.0, kl=3400.0, ku=4000.0)
    x = np.round(x / ENCODER_STEP) * ENCODER_STEP
    f = f + 0.03 * rng.standard_normal(f.size)
    fit = fit_trial(t, x, f)
    assert fit.n_strokes == 1
    assert fit.stiffness == pytest.approx(4000.0, rel=0.01)
    assert fit.loading_slope == pytest.approx(3400.0, rel=0.02)


@settings(max_examples=40, deadline=None)
@given(ku=st.floats(1000.0, 20000.0), ratio=st.floats(0.5, 1.0),
       depth=st.floats(1.0, 8.0), rate=st.sampled_from([100.0, 173.0, 250.0, 500.0]),
       offset=st.floats(-5.0, 5.0), x0=st.floats(-50.0, 50.0))
def test_noiseless_push_recovers_both_slopes(ku, ratio, depth, rate, offset, x0):
    kl = ratio * ku
    t, d = profile([(0, -1 * MM), (3.5, -1 * MM), (4.5, 0), (6.0, depth * MM),
                    (7.5, -1 * MM), (8.0, -1 * MM)], rate)
    f = hysteretic_force(t, d, [(0, 9, kl, ku)]) + offset
    fit = fit_trial(t, x0 * MM + d, f)
    assert fit.stiffness == pytest.approx(ku, rel=1e-8)
    assert fit.loading_slope == pytest.approx(kl, rel=1e-8)
    assert fit.hysteresis_ratio == pytest.approx(1 - ratio, abs=5e-3)


# --------------------------------------------------------------------------- zeroing and onset


@pytest.mark.parametrize("offset,sd,seed", [(-3.2, 0.04, 1), (2.5, 0.01, 2), (0.0, 0.1, 3)])
def test_onset_on_noisy_baseline_with_offset(offset, sd, seed):
    rng = np.random.default_rng(seed)
    rate, t_c, slope = 500.0, 5.0, 20.0            # force ramps up at 20 N/s from t = 5 s
    t = np.arange(int(8 * rate)) / rate
    f = offset + slope * np.maximum(t - t_c, 0) + sd * rng.standard_normal(t.size)
    n_win = int(np.count_nonzero(t < 3.0))
    level, noise = zero_level(t, f, 3.0)
    assert level == pytest.approx(offset, abs=5 * sd / np.sqrt(n_win))
    assert noise == pytest.approx(sd, rel=0.1)
    thr = default_onset_threshold(noise)
    assert thr == pytest.approx(max(5 * noise, 0.05))
    i = detect_onset(f - level, thr)
    # expected: the ramp crosses the threshold at t_c + thr/slope, give or take the noise
    assert abs(t[i] - (t_c + thr / slope)) <= 4 * sd / slope + 1 / rate
    # with an explicit threshold of 1 N: t_c + 1/20 s
    i1 = detect_onset(f - level, 1.0)
    assert abs(t[i1] - (t_c + 1.0 / slope)) <= 4 * sd / slope + 1 / rate


def test_onset_threshold_floor_for_noiseless_force():
    assert default_onset_threshold(0.0) == pytest.approx(0.05)
    assert default_onset_threshold(0.02) == pytest.approx(0.1)


def test_no_indentation_is_an_error():
    t = np.arange(1000) / 100.0
    f = 0.3 + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    with pytest.raises(TrialError, match="no indentation") as err:
        fit_trial(t, np.zeros_like(t), f)
    assert err.value.key == "force"


def test_trial_shorter_than_zero_window_is_an_error():
    t = np.arange(250) / 100.0                      # 2.49 s
    with pytest.raises(TrialError, match="zero window") as err:
        fit_trial(t, np.zeros_like(t), np.zeros_like(t))
    assert err.value.key == "time"


def test_indentation_inside_zero_window_is_an_error():
    t, d = profile([(0, 0), (1, 0), (2, 3 * MM), (3, 0), (6, 0)], 100.0)
    with pytest.raises(TrialError, match="inside the zero window"):
        fit_trial(t, d, 4000.0 * d, onset_threshold=0.5)


def test_trial_without_unloading_is_an_error():
    # the recording stops at the deepest point
    t, d = profile([(0, -1 * MM), (4, -1 * MM), (5, 0), (7, 3 * MM)], 100.0)
    with pytest.raises(TrialError, match="no unloading stroke"):
        fit_trial(t, d, 4000.0 * np.maximum(d, 0))


def test_nan_and_time_order_are_errors():
    t, x, f = single_push()
    f2 = f.copy()
    f2[10] = np.nan
    with pytest.raises(TrialError) as err:
        fit_trial(t, x, f2)
    assert err.value.key == "force"
    t2 = t.copy()
    t2[50] = t2[49]
    with pytest.raises(TrialError) as err:
        fit_trial(t2, x, f)
    assert err.value.key == "time"


# --------------------------------------------------------------------------- strokes


def test_turning_points_plateau_first_and_last():
    x = np.array([0, 1, 2, 3, 3, 3, 2, 1, 0, 1, 2, 1.0])
    maxima, minima = turning_points(x, 1.5)
    np.testing.assert_array_equal(maxima, [[3, 5]])
    np.testing.assert_array_equal(minima, [[8, 8]])


def test_turning_points_ignore_encoder_steps_and_tremor():
    rng = np.random.default_rng(3)
    rate = 200.0
    # three pushes to 3, 4.5 and 2 mm, with 10 Hz tremor of 0.03 mm and encoder steps
    t, d = profile([(0, -1 * MM), (3, -1 * MM), (4, 3 * MM), (5, -1 * MM), (6, 4.5 * MM),
                    (7.2, -1 * MM), (8, 2 * MM), (9, -1 * MM), (9.5, -1 * MM)], rate)
    d = d + 0.03 * MM * np.sin(2 * np.pi * 10 * t + rng.uniform(0, 6))
    d = np.round(d / ENCODER_STEP) * ENCODER_STEP
    maxima, minima = turning_points(d, 0.1 * MM)
    assert len(maxima) == 3
    assert len(minima) == 2
    np.testing.assert_allclose(t[maxima[:, 0]], [4.0, 6.0, 8.0], atol=0.06)
    pushes = split_strokes(d, 0.1 * MM)
    assert len(pushes) == 3
    for (a, hf, hl, b), (a2, _, _, _) in zip(pushes, pushes[1:] + [(len(d), 0, 0, 0)]):
        assert a <= hf <= hl < b <= a2 + 1


def test_hand_hesitation_does_not_split_a_push():
    # loading to 4 mm with a 0.2 mm back-off at 2 mm (more than encoder steps and tremor,
    # less than 10 % of the depth): one push, one unloading stroke
    t, d = profile([(0, -1 * MM), (4, -1 * MM), (5, 0), (6, 2 * MM), (6.2, 1.8 * MM),
                    (7.5, 4 * MM), (9, -1 * MM), (10, -1 * MM)], 100.0)
    f = 4000.0 * np.maximum(d, 0)
    fit = fit_trial(t, d, f)
    assert fit.n_strokes == 1
    assert fit.stiffness == pytest.approx(4000.0, rel=1e-9)
    # with an explicit small reversal the back-off is a stroke of its own
    assert fit_trial(t, d, f, reversal=0.1 * MM).n_strokes == 2


def test_split_strokes_single_push_bounds():
    x = np.array([0, 0, 1, 2, 3, 4, 4, 3, 2, 1, 0, 0.0])
    assert split_strokes(x, 1.5) == [(0, 5, 6, 12)]


def test_fit_line_closed_form():
    x = np.array([0.0, 1.0, 2.0, 3.0])
    y = np.array([1.0, 3.0, 2.0, 5.0])
    # slope = Sxy/Sxx = (3.5+... ) by hand: xm = 1.5, ym = 2.75
    # Sxx = 5, Sxy = (-1.5)(-1.75)+(-0.5)(0.25)+(0.5)(-0.75)+(1.5)(2.25) = 5.5
    slope, intercept, r2 = fit_line(x, y)
    assert slope == pytest.approx(1.1)
    assert intercept == pytest.approx(2.75 - 1.1 * 1.5)
    # SS_tot = 3.0625+0.0625+0.5625+5.0625 = 8.75; SS_reg = 1.1^2 * 5 = 6.05
    assert r2 == pytest.approx(6.05 / 8.75)


# --------------------------------------------------------------------------- locations


def _trial_with_slope(ku, kl=None, rate=100.0):
    t, x, f = single_push(rate=rate, kl=kl or 0.9 * ku, ku=ku)
    return fit_trial(t, x, f)


def test_location_mean_sd_count_and_spread_flag():
    trials = [_trial_with_slope(4000.0), _trial_with_slope(4400.0)]
    loc = fit_location(trials, location="B3", trial_ids=[1, 2], max_spread=0.05)
    assert loc.stiffness == pytest.approx(4200.0, rel=1e-9)
    assert loc.std == pytest.approx(200.0 * np.sqrt(2.0), rel=1e-9)   # ddof = 1
    assert loc.n_trials == 2
    assert loc.spread == pytest.approx(400.0 / 4200.0, rel=1e-9)
    assert loc.flags == ("trial_spread",)
    loc2 = fit_location(trials, location="B3", max_spread=0.10)
    assert loc2.flags == ()


def test_single_trial_has_nan_sd_and_flag():
    loc = fit_location([_trial_with_slope(4000.0)], location="A0")
    assert loc.n_trials == 1
    assert np.isnan(loc.std)
    assert loc.spread == 0.0
    assert "single_trial" in loc.flags
    mean, sd, n = location_statistics([4000.0])
    assert (mean, n) == (4000.0, 1) and np.isnan(sd)
    assert trial_spread([1.0]) == 0.0


def test_low_r2_flag_on_curved_unloading():
    # unloading along a parabola: F = 4000 d + 8e5 d^2 (curved), loading a line
    t, d = profile([(0, -1 * MM), (4, -1 * MM), (5, 0), (7, 3 * MM), (9, 0), (10, 0)], 100.0)
    peak = int(np.argmax(d))
    f = np.where(np.arange(d.size) <= peak, 4000 * d + 8e5 * 3 * MM * d,
                 4000 * d + 8e5 * d ** 2)
    f = np.maximum(f, 0)
    fit = fit_trial(t, d, f)
    assert fit.r2_min < 0.999
    loc = fit_location([fit, fit], min_r2=0.9995)
    assert "low_r2" in loc.flags
    assert "low_r2" not in fit_location([fit, fit], min_r2=0.5).flags


# --------------------------------------------------------------------------- generator


def test_generator_is_fixed_seed_and_labelled():
    a = synth_trial(4242.0, rate=200.0, seed=3)
    b = synth_trial(4242.0, rate=200.0, seed=3)
    np.testing.assert_array_equal(a.force, b.force)
    steps = a.displacement / ENCODER_STEP
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    assert a.time[0] == 0 and np.diff(a.time) == pytest.approx(1 / 200.0)


def test_truth_map_has_paper_mean_and_sd():
    tm = truth_map(seed=11)
    v = np.array(list(tm.values()))
    assert list(tm)[:3] == ["A0", "A1", "A2"] and len(tm) == 21
    assert v.mean() == pytest.approx(4242.0)
    assert v.std(ddof=1) == pytest.approx(251.5)


@pytest.mark.parametrize("rate", [100.0, 250.0, 500.0])
def test_generated_trials_recover_stiffness_within_one_percent(rate):
    truth = truth_map(seed=123)
    trials = synth_dataset(truth, seed=77, rates=(rate,))
    by_loc = {}
    for tr in trials:
        fit = fit_trial(tr.time, tr.displacement, tr.force)
        assert fit.n_strokes == tr.n_pushes
        by_loc.setdefault(tr.location, []).append(fit)
    for lab, fits in by_loc.items():
        loc = fit_location(fits, location=lab)
        assert loc.stiffness == pytest.approx(truth[lab], rel=0.01), lab


def test_generated_hysteresis_and_loading_slope():
    tr = synth_trial(5000.0, rate=300.0, seed=9, hysteresis=0.2, n_pushes=2)
    fit = fit_trial(tr.time, tr.displacement, tr.force)
    assert fit.stiffness == pytest.approx(5000.0, rel=0.01)
    assert fit.loading_slope == pytest.approx(0.8 * 5000.0, rel=0.02)
    assert fit.hysteresis_ratio == pytest.approx(0.2, abs=0.02)


def test_generated_reversed_encoder():
    tr = synth_trial(3800.0, rate=150.0, seed=4, encoder_sign=-1)
    fit = fit_trial(tr.time, tr.displacement, tr.force)
    assert fit.sign == -1
    assert fit.stiffness == pytest.approx(3800.0, rel=0.01)
