"""Issue 6, acceptance 5 (the part a test can prove without a trained policy): whatever a policy
answers, on every real Klipper resonance file the recommendation is within the firmware's ranges.

The policy's action is the whole box [-1, 1]^n; a stub policy answers its corners, centre and random
points, and the real recommendation path (`recommend_from_psd`: file -> PSD -> model fitted to it ->
observation with the starting answer's simulated metrics -> peak-anchored decoding) turns each into
a TuneConfig. "Within the firmware's ranges" is judged by
`hardware.dialects.export_config`, whose Klipper ranges follow firmware.md §1.5 (shaper_freq > 0,
damping ≤ the shaper's maximum, a shaper Klipper has), plus Klipper's own calibration range for F.
The table beside Klipper's rule with a trained policy is printed by
`benchmarks/bench_ppo.py --real-only --policy DIR`.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from ringtune.agents.ppo import policy as ppo  # noqa: E402
from ringtune.agents.identify.accelerometer import resonance_psds  # noqa: E402
from ringtune.agents.ppo import recommend as ppo_recommend  # noqa: E402
from ringtune.agents.ppo.recommend import axis_spectra  # noqa: E402


class _StubPolicy(ppo.Policy):
    """A 'policy' that answers a fixed action (no pickles, no training)."""

    def __init__(self, action=None):
        super().__init__(model=None, vecnorm=None, meta={"env_kwargs": ppo.resolve_env_kwargs()}, path=".")
        self.action = action

    def act(self, obs):
        assert np.all(np.isfinite(obs)) and np.all(np.abs(obs) <= 1.0)
        return np.asarray(self.action, np.float32)


def _actions(n: int) -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    fixed = [np.full(n, v, np.float32) for v in (-1.0, 0.0, 1.0)]
    alternating = [np.where(np.arange(n) % 2 == k, 1.0, -1.0).astype(np.float32) for k in (0, 1)]
    return fixed + alternating + [rng.uniform(-1, 1, n).astype(np.float32) for _ in range(12)]


def test_every_policy_answer_on_every_real_file_is_within_klippers_ranges(data_dir):
    from ringtune.hardware.dialects import export_config

    root = data_dir / "accel" / "klipper_psd"
    folders = sorted(p for p in root.iterdir() if p.is_dir() and list(p.glob("resonances_*.csv")))
    assert len(folders) == 6
    n = _StubPolicy().make_env().spec_.size
    for folder in folders:
        psds, _ = resonance_psds(sorted(str(f) for f in folder.glob("resonances_*.csv")), None)
        spectra = axis_spectra(psds)
        env, obs = ppo_recommend.measured_observation(_StubPolicy(), spectra)
        assert np.all(np.isfinite(obs)) and np.all(np.abs(obs) <= 1.0)
        assert env.start_metrics_ is not None          # the starting answer simulated on the fitted model
        for action in _actions(n):
            cfg = ppo_recommend.decode_measured(env, action, spectra)
            cfg.validate()
            text = export_config(cfg).render()            # raises on anything outside Klipper's ranges
            assert "SET_INPUT_SHAPER" in text
            for ax in ("x", "y"):
                name, f, z = cfg.axis(ax)
                if ax not in psds:
                    assert name == "none", (folder.name, ax)
                    continue
                if name != "none":   # "none" (shaping off) is a valid answer on a measured axis too
                    assert 5.0 <= f <= 200.0, (folder.name, ax, f)     # Klipper's MIN_FREQ..MAX_FREQ
            assert cfg.accel is not None and 0 < cfg.accel <= 1e5
            assert cfg.freq_limit_hz == 0.0 or cfg.freq_limit_hz > 0
