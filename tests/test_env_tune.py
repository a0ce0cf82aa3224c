"""The gymnasium environments: both checkers, seeded determinism, action decoding, reward."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import ringtune.envs  # noqa: F401  (registers the ids)
from ringtune.envs.actions import ActionSpec, decode_action, encode_config
from ringtune.envs.env import TuneEnv
from ringtune.envs.random_printer import random_printer_dict
from ringtune.envs.printer import printer_from_dict
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError


def test_registered_one_shot_without_time_limit():
    for env_id, randomize in (("ringtune/Tune-v0", True), ("ringtune/TuneFixed-v0", False)):
        spec = gym.spec(env_id)
        assert spec.max_episode_steps is None and spec.kwargs["randomize"] is randomize
    env = gym.make("ringtune/TuneFixed-v0", backend="lti")
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    obs, r, terminated, truncated, info = env.step(env.action_space.sample())
    assert terminated and not truncated and math.isfinite(r)
    assert set(info["metrics"]) >= {"print_time_s", "path_error_mm", "overshoot_mm", "ringing_mm",
                                    "peak_accel", "step_loss"}
    env.close()


@pytest.mark.slow
def test_gymnasium_check_env_passes():
    from gymnasium.utils.env_checker import check_env

    for env_id in ("ringtune/TuneFixed-v0", "ringtune/Tune-v0"):
        # the registered env, unwrapped (the checker wants the bare env; make gives it its spec)
        env = gym.make(env_id, backend="lti", observe_metrics=False, render_mode="rgb_array").unwrapped
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # a checker warning is a failure too
            check_env(env, skip_render_check=False)
        env.close()


@pytest.mark.slow
def test_stable_baselines3_check_env_passes():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_checker import check_env

    env = TuneEnv(randomize=True, backend="lti", observe_metrics=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, warn=True)
    env.close()


@pytest.mark.slow
def test_both_checkers_pass_on_the_default_environment():
    """As registered, with its defaults: MuJoCo physics and the last metrics in the observation."""
    pytest.importorskip("stable_baselines3")
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make("ringtune/TuneFixed-v0").unwrapped
    assert env.backend == "mujoco" and env.observe_metrics
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, skip_render_check=True)
        sb3_check_env(env, warn=True)
    env.close()


def _episode(env, seed, action):
    obs0, info0 = env.reset(seed=seed)
    obs1, r, term, trunc, info1 = env.step(action)
    return obs0, obs1, r, info0, info1


@pytest.mark.parametrize("backend", ["lti", "mujoco"])
def test_seeded_reset_gives_identical_episodes(backend):
    a = TuneEnv(randomize=True, backend=backend)
    b = TuneEnv(randomize=True, backend=backend)
    action = np.linspace(-0.9, 0.9, a.action_space.shape[0]).astype(np.float32)
    ea, eb = _episode(a, 123, action), _episode(b, 123, action)
    for x, y in zip(ea[:2], eb[:2]):
        assert np.array_equal(x, y)
    assert ea[2] == eb[2] and ea[4] == eb[4]
    assert a.printer.to_dict() == b.printer.to_dict()
    # another seed: another printer and another spectrum
    ec = _episode(b, 124, action)
    assert b.printer.to_dict() != a.printer.to_dict()
    assert not np.array_equal(ec[0], ea[0])


def test_observation_shows_the_resonances():
    """The spectrum part of the observation peaks in the bins of the printer's modes."""
    printer = printer_from_dict({"name": "two-mode", "x": {"modes": [{"freq": 72.0, "damping": 0.05}]},
                                 "y": {"modes": [{"freq": 33.0, "damping": 0.05}]}})
    env = TuneEnv(printer, backend="lti", observe_metrics=False)
    n = env.n_bins
    lo, hi = env.spectrum_range
    width = (hi - lo) / n
    for seed in (1, 2):
        obs, _ = env.reset(seed=seed)
        for part, f_mode in ((obs[:n], 72.0), (obs[n:2 * n], 33.0)):
            assert abs(lo + (int(np.argmax(part)) + 0.5) * width - f_mode) <= width
        assert obs[:2 * n].max() == pytest.approx(1.0)
    # the config part shows shaping off and the metrics part is empty without observe_metrics
    assert np.array_equal(obs[2 * n:2 * n + env.action_space.shape[0]],
                          encode_config(env.config, env.spec_))
    assert not obs[-6:].any()


def test_reward_is_tunes_judgement_against_the_baseline():
    """r = −(w_time·T/T0 + w_worse·Σ relative excess over the baseline beyond the resolution +
    constraints), the baseline (MZV on the peaks at the printer's accel) evaluated independently."""
    from ringtune.envs.evaluate import evaluate
    from ringtune.envs.judgement import JUDGED_KEYS, baseline_config

    w = {"time": 2.0, "worse": 3.0}
    env = TuneEnv(backend="lti", weights=w, step_loss_penalty=7.0, observe_metrics=False)
    _, info0 = env.reset(seed=0)
    base_cfg = baseline_config(env.peaks_, "klipper", env.printer.limits.accel)
    assert info0["baseline_config"] == base_cfg.to_dict()
    b = evaluate(base_cfg, env.printer, None, backend="lti").to_dict()
    cfg = TuneConfig(shaper_x="zv", shaper_y="zv", freq_x=30.0, freq_y=30.0, accel=9000.0)
    _, r, *_, info = env.step(encode_config(cfg, env.spec_))
    m = info["metrics"]
    worse = 0.0
    for k in JUDGED_KEYS:
        tol = max(1.0 if k.endswith("_pct") else 0.001, 0.05 * max(m[k], b[k]))   # pct: percentage points
        worse += np.log1p(max(0.0, m[k] - b[k] - tol) / max(b[k], tol))
    assert worse > 0                                    # ZV far below the modes at 9000 mm/s² rings more
    load = 7.0 * max(0.0, m["motor_load"] - 0.8) / 0.2 + 7.0 * max(0.0, m["path_error_mm"] - 0.1) / 0.1
    expect = -(2.0 * m["print_time_s"] / info["baseline_print_time_s"] + 3.0 * worse + load
               + (7.0 if m["step_loss"] else 0.0))
    assert r == pytest.approx(expect, rel=1e-9)
    # the baseline itself pays only its print time ratio (1: it runs at the printer's own accel)
    _, r0, *_ = env.step(encode_config(base_cfg, env.spec_))
    assert r0 == pytest.approx(-2.0, rel=1e-3)
    with pytest.raises(RingtuneError, match="weights"):
        TuneEnv(weights={"speed": 1.0})


def test_decode_action_extremes():
    spec = ActionSpec(tune_accel=True)
    lo = decode_action(-np.ones(spec.size), spec)
    hi = decode_action(np.ones(spec.size), spec)
    assert (lo.shaper_x, lo.freq_x, lo.damping_x, lo.freq_limit_hz, lo.accel) == (
        spec.shapers[0], 15.0, 0.02, 0.0, 1000.0)
    assert hi.shaper_y == spec.shapers[-1] and hi.freq_y == pytest.approx(150.0)
    assert hi.freq_limit_hz == pytest.approx(120.0) and hi.accel == pytest.approx(10000.0)
    mid = decode_action(np.zeros(spec.size), spec)
    assert mid.freq_x == pytest.approx(math.sqrt(15.0 * 150.0))  # log scale: geometric mean
    assert mid.shaper_x == spec.shapers[len(spec.shapers) // 2]
    with pytest.raises(RingtuneError, match="entries"):
        decode_action(np.zeros(3), spec)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 6), st.floats(15, 150), st.floats(0.02, 0.2), st.integers(0, 6),
       st.floats(15, 150), st.floats(0.02, 0.2), st.one_of(st.just(0.0), st.floats(11, 120)))
def test_encode_then_decode_gives_the_config_back(kx, fx, sx, ky, fy, sy, limit):
    spec = ActionSpec()
    cfg = TuneConfig(shaper_x=spec.shapers[kx], freq_x=fx, damping_x=sx, shaper_y=spec.shapers[ky],
                     freq_y=fy, damping_y=sy, freq_limit_hz=limit)
    back = decode_action(encode_config(cfg, spec), spec)
    assert (back.shaper_x, back.shaper_y) == (cfg.shaper_x, cfg.shaper_y)
    assert back.freq_x == pytest.approx(fx, rel=1e-5) and back.freq_y == pytest.approx(fy, rel=1e-5)
    assert back.damping_x == pytest.approx(sx, abs=1e-6) and back.damping_y == pytest.approx(sy, abs=1e-6)
    assert back.freq_limit_hz == pytest.approx(limit, abs=1e-4)


def test_random_printers_cover_the_documented_ranges():
    rng = np.random.default_rng(7)
    freqs, damps, kins = [], [], set()
    for _ in range(200):
        d = random_printer_dict(rng)
        p = printer_from_dict(d)  # always valid
        kins.add(p.kinematics)
        for ax in ("x", "y"):
            freqs.append(d[ax]["modes"][0]["freq"])
            damps.append(d[ax]["modes"][0]["damping"])
    assert 20.0 <= min(freqs) < 25.0 and 110.0 < max(freqs) <= 130.0
    assert 0.02 <= min(damps) < 0.03 and 0.15 < max(damps) <= 0.2
    assert kins == {"cartesian", "corexy"}


def test_rejected_configuration_ends_with_the_penalty(monkeypatch):
    env = TuneEnv(backend="lti", observe_metrics=False, step_loss_penalty=4.0)
    env.reset(seed=0)

    def refuse(config):
        raise RingtuneError("impulses collide on the firmware's time grid", "shaper")

    monkeypatch.setattr(env, "evaluate", refuse)
    obs, r, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, np.float32))
    assert r == -4.0 and terminated and not truncated and "collide" in info["error"]
    assert env.observation_space.contains(obs)


# -- peak-anchored frequencies and the gated frequency limit ------------------------------------------
def test_peak_anchored_decoding_is_a_residual_around_each_axis_peak():
    spec = ActionSpec(freq_anchor="peak", freq_limit_gate=True)
    peaks = (40.0, 90.0)
    mid = decode_action(np.zeros(spec.size), spec, peaks)
    assert (mid.freq_x, mid.freq_y) == (pytest.approx(40.0), pytest.approx(90.0))
    a = np.zeros(spec.size)
    a[1], a[4] = 1.0, -1.0
    c = decode_action(a, spec, peaks)
    assert c.freq_x == pytest.approx(80.0) and c.freq_y == pytest.approx(45.0)  # one octave up / down
    a[4] = 1.0
    assert decode_action(a, spec, peaks).freq_y == pytest.approx(150.0)  # 180 Hz clipped to freq_range
    # the frequency limit is off for the whole lower half of its entry, then spans 10-120 Hz
    for v, hz in ((-1.0, 0.0), (0.0, 0.0), (0.5, 65.0), (1.0, 120.0)):
        a[6] = v
        assert decode_action(a, spec, peaks).freq_limit_hz == pytest.approx(hz)
    with pytest.raises(RingtuneError, match="peaks"):
        decode_action(np.zeros(spec.size), spec)


@settings(max_examples=40, deadline=None)
@given(st.floats(20, 130), st.floats(20, 130), st.floats(-0.99, 0.99), st.floats(-0.99, 0.99),
       st.one_of(st.just(0.0), st.floats(11, 120)))
def test_peak_anchored_encode_then_decode_gives_the_config_back(px, py, vx, vy, limit):
    spec = ActionSpec(freq_anchor="peak", freq_limit_gate=True)
    fx = min(max(px * 2.0 ** vx, 15.0), 150.0)
    fy = min(max(py * 2.0 ** vy, 15.0), 150.0)
    cfg = TuneConfig(shaper_x="ei", freq_x=fx, damping_x=0.1, shaper_y="mzv", freq_y=fy, damping_y=0.05,
                     freq_limit_hz=limit)
    back = decode_action(encode_config(cfg, spec, (px, py)), spec, (px, py))
    assert back.freq_x == pytest.approx(fx, rel=1e-5) and back.freq_y == pytest.approx(fy, rel=1e-5)
    assert back.freq_limit_hz == pytest.approx(limit, abs=1e-4)


def test_peak_env_finds_the_modes_and_observes_them():
    from ringtune.envs.observation import peak_features

    printer = printer_from_dict({"name": "two-mode", "x": {"modes": [{"freq": 72.0, "damping": 0.05}]},
                                 "y": {"modes": [{"freq": 33.0, "damping": 0.05}]}})
    env = TuneEnv(printer, backend="lti", observe_metrics=False, freq_anchor="peak", freq_limit_gate=True)
    obs, info = env.reset(seed=3)
    fx, fy = info["peaks_hz"]
    assert abs(fx - 72.0) <= 3.2 and abs(fy - 33.0) <= 3.2  # two of Klipper's 1.5625 Hz bins
    assert obs.shape == env.observation_space.shape and env.observation_space.contains(obs)
    np.testing.assert_array_equal(obs[-2:], peak_features((fx, fy), env.spectrum_range))
    # peak_features is the log position in the spectrum range: 10 Hz -> -1, 160 Hz -> 1
    np.testing.assert_allclose(peak_features((10.0, 160.0)), [-1.0, 1.0], atol=1e-6)
    a = np.zeros(env.action_space.shape, np.float32)
    _, _, _, _, info = env.step(a)
    assert info["config"]["freq_x"] == pytest.approx(fx) and info["config"]["freq_y"] == pytest.approx(fy)
    assert info["config"]["freq_limit_hz"] == 0.0
    with pytest.raises(RingtuneError, match="freq_anchor"):
        TuneEnv(freq_anchor="relative")
