"""Klipper's parametrised shapers in the search: mzv(n=…, t=…) and ei(v_tol=…) are searched where
the firmware has them (Klipper HEAD's formulas), every sampled point is a shaper Klipper accepts,
and a configuration round-trips through the search parameters."""

from __future__ import annotations

import numpy as np
import optuna
import pytest

from ringtune.agents.tune.shaper_families import MZV_N, mzv_t_max
from ringtune.agents.tune.space import config_from_params, default_space, params_from_config, suggest_params
from ringtune.envs.evaluate import evaluate
from ringtune.envs.printer import load_printer
from ringtune.shaping.analysis import residual_vibration
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.shapers import get_shaper, shapers_from_config


@pytest.fixture(scope="module")
def printer():
    return load_printer("ender3")


def test_only_klippers_formulas_are_searched_with_parameters(printer):
    assert {"mzv(n,t)", "ei(v_tol)"} <= set(default_space(printer, "klipper").shapers)
    for fw in ("rrf", "marlin", "marlin-ftm", "prusa"):
        assert not any("(" in s for s in default_space(printer, fw).shapers), fw


def test_every_sampled_point_is_a_shaper_klipper_accepts(printer):
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    space = default_space(printer, "klipper")
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=3))
    names = set()
    for _ in range(300):
        trial = study.ask()
        cfg = config_from_params(suggest_params(trial, space), space)
        shapers, _ = shapers_from_config(cfg)             # raises on a shaper Klipper would refuse
        for ax in ("x", "y"):
            name = getattr(cfg, f"shaper_{ax}")
            names.add(name.split("(")[0] + ("(…)" if "(" in name else ""))
            if "(" in name:
                assert config_from_params(params_from_config(cfg, space), space).axis(ax) == cfg.axis(ax)
        study.tell(trial, 0.0)
    assert {"mzv(…)", "ei(…)", "mzv", "ei"} <= names


@pytest.mark.parametrize("n", range(MZV_N[0], MZV_N[1] + 1))
def test_the_duration_range_is_the_one_klippers_generalised_mzv_allows(n):
    for t in (0.5, round(mzv_t_max(n), 2)):
        s = get_shaper(f"mzv(n={n},t={t:g})", 40.0, 0.1)
        assert len(s.amplitudes) == n and np.all(s.amplitudes >= -1e-5)
        assert s.duration == pytest.approx(t / (40.0 * np.sqrt(1 - 0.01)), rel=1e-9)   # t damped periods


def test_v_tol_is_the_vibration_ei_leaves_at_its_frequency():
    """Undamped EI's defining property: v_tol of the vibration remains at the design frequency (Klipper's
    EI is a polynomial fit of that shaper: within 7 %)."""
    for v in (0.02, 0.1, 0.2):
        s = get_shaper(f"ei(v_tol={v})", 50.0, 0.0)
        assert float(residual_vibration(s, [50.0], 0.0)[0]) == pytest.approx(v, rel=0.07)


def test_a_parametrised_configuration_is_judged(printer):
    cfg = TuneConfig(firmware="klipper", shaper_x="mzv(n=5,t=1.1)", shaper_y="ei(v_tol=0.1)", freq_x=45.0,
                     freq_y=40.0, accel=3000)
    m = evaluate(cfg, printer, None, backend="lti")
    plain = evaluate(TuneConfig(firmware="klipper", shaper_x="none", shaper_y="none", accel=3000), printer, None,
                     backend="lti")
    assert m.ringing_mm < plain.ringing_mm
