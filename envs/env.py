"""Gymnasium environments: choose an input-shaping configuration for a (simulated) printer.

Registered ids (see ``ringtune.envs``): ``ringtune/Tune-v0`` (a new random printer every episode)
and ``ringtune/TuneFixed-v0`` (one fixed printer, default the embedded Ender-3-class machine).
The action encoding is :mod:`ringtune.envs.actions`, the observation's spectrum parts
:mod:`ringtune.envs.observation`, the randomised printers :mod:`ringtune.envs.random_printer`,
the checks of the arguments :mod:`ringtune.envs.env_arguments`.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import matplotlib
import numpy as np
from gymnasium import spaces
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ringtune.envs.accel_model import model_accel
from ringtune.envs.actions import ActionSpec, decode_action, encode_config
from ringtune.envs.env_arguments import check_anchors, checked_shapers, checked_start_action, over_defaults
from ringtune.envs.evaluate import evaluate_many
from ringtune.envs.planned_job import planned_job, resolve_printer
from ringtune.envs.judgement import DEFAULT_WEIGHTS, JUDGEMENT, baseline_config, judged_cost
from ringtune.envs.metrics import Metrics
from ringtune.envs.mujoco_model import linear_system
from ringtune.envs.observation import log_position, peak_features, spectrum_features, spectrum_peaks
from ringtune.envs.printer import printer_from_dict
from ringtune.envs.random_printer import random_printer_dict
from ringtune.envs.sim import resonance_test
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError

#: scales s in the squashing m / (m + s) of the observed metrics
METRIC_SCALES = {"time_ratio": 1.0, "path_error_mm": 0.1, "overshoot_mm": 0.1, "ringing_mm": 0.02}
#: entries of the observation's metrics part (see :class:`TuneEnv`)
N_METRICS = 7


# -- the environment ---------------------------------------------------------------------------------
class TuneEnv(gym.Env):
    """Choose an input-shaping configuration for a printer; one shot per episode.

    ## Description
    A printer (a fixed one, or a new random one each episode) is shown to the agent the way a
    person tuning it sees it: the spectrum of a resonance test recorded by an accelerometer on the
    toolhead, plus the current configuration and its metrics. The agent answers with a complete
    configuration (shaper type, frequency F and damping S per axis, infill frequency limit,
    optionally the acceleration). The configuration is evaluated by
    :func:`ringtune.envs.evaluate.evaluate`: print time over the whole job from the planner,
    quality from the MuJoCo printer on the job's sharpest corners and fastest zigzags.

    ## Action Space
    ``Box(-1, 1, (n,), float32)``, decoded by :func:`decode_action` with the env's
    :class:`ActionSpec`; ``n`` = 7 per axis (type, F, S for X, then Y, then frequency limit) or 4
    shared (type, F, S, frequency limit), +1 with ``tune_accel``.

    | index | meaning (per_axis) | decoding |
    |---|---|---|
    | 0, 3 | shaper type X, Y | equal bins over ``spec.shapers`` |
    | 1, 4 | F X, Y (Hz) | ``freq_anchor="absolute"``: log scale over ``spec.freq_range``; ``"peak"``: ``f_peak·2^v`` (v = the value in [-1, 1], ``f_peak`` the axis's resonance peak, :func:`spectrum_peaks`), clipped to ``freq_range`` |
    | 2, 5 | S X, Y | linear over ``spec.damping_range`` |
    | 6 | frequency limit (Hz) | linear 0–``freq_limit_max``, off at ≤ ``freq_limit_off``; with ``freq_limit_gate``: off for values ≤ 0, linear ``freq_limit_off``–``freq_limit_max`` over (0, 1] |
    | 7 | acceleration (mm/s², only with ``tune_accel``) | log scale over ``accel_range`` |

    With ``freq_anchor="peak"`` the action is a residual around a physical anchor: 0 puts the
    shaper on the resonance peak the spectrum shows, ±1 an octave above/below. The peaks come from
    the same resonance test as the observation (``self.peaks_``), so the decoding transfers to
    measured spectra, whose absolute frequencies differ from the simulated ones.

    ## Observation Space
    ``Box(-1, 1, (2·n_bins + n + 7 [+ 2] [+ 1],), float32)`` (+2 with ``freq_anchor="peak"``, +1
    with ``accel_anchor="model"``):

    | slice | meaning |
    |---|---|
    | ``[0, n_bins)`` | X resonance-test PSD, mean per bin of ``n_bins`` equal bins over ``spectrum_range`` Hz, ``1 + log10(psd/max)/3`` clipped to [-1, 1] (0 dB → 1, −60 dB → −1; X and Y share the max) |
    | ``[n_bins, 2·n_bins)`` | the same for Y |
    | next ``n`` | the current configuration, encoded as an action (:func:`encode_config`) |
    | next 7 | its metrics squashed as ``m/(m+s)``: print time / baseline print time (s = 1), path error (s = 0.1 mm), overshoot (0.1 mm), ringing (0.02 mm), peak acceleration (s = the printer's accel), step loss (0/1), motor load (s = 1) |
    | next 2 (``freq_anchor="peak"`` only) | the resonance peaks X, Y (:func:`spectrum_peaks`), ``2·ln(f/lo)/ln(hi/lo) − 1`` over ``spectrum_range`` (:func:`peak_features`) |
    | last 1 (``accel_anchor="model"`` only) | the anchor acceleration ``accel_anchor_``, ``2·ln(a/lo)/ln(hi/lo) − 1`` over ``accel_range`` |

    With ``accel_anchor="model"`` (needs ``observe_metrics``) the acceleration entry is a residual
    around ``accel_anchor_``: the acceleration at which the starting configuration's metrics,
    scaled linearly with acceleration, give the lowest cost with a 30 % motor force reserve
    (:func:`ringtune.envs.accel_model.model_accel`); the starting action itself decodes with
    ``spec_.accel_start``.

    At reset the current configuration is ``options["config"]``, else ``start_action`` decoded on
    the printer's peaks, else shaping off with no frequency limit; its metrics are evaluated when
    ``observe_metrics`` (else zeros) and kept as ``start_metrics_``. After the step they are the
    chosen configuration and its metrics.

    ## Rewards
    ``r = −cost``, ``tune``'s judgement as one number (:mod:`ringtune.envs.judgement`): the print
    time over ``T0`` (the job at the printer's own acceleration without frequency limit), plus
    ``weights["worse"]`` × the summed relative excess of every judged measure (ripple, corners,
    extrusion, show-through) over the baseline's beyond the resolution, plus the constraints
    (``step_loss_penalty`` for lost steps; the same × the relative excess over the motor reserve
    and the path-error bound). The baseline is MZV on each axis's resonance peak at the printer's
    own acceleration (:func:`ringtune.envs.judgement.baseline_config`), evaluated at reset
    (``baseline_metrics_``; one more evaluation per printer). Every evaluation is judged as
    ``tune`` judges, on the printer and, with ``freq_margin``, its twins with every resonance that
    fraction lower and higher (the worst counts, and a measure's excess is the largest over the
    worst and on each of them). A configuration the firmware rejects (e.g.
    impulses colliding on its time grid) ends the episode with reward ``−step_loss_penalty``.

    ## Starting State
    Fixed env: the given printer. Randomised env: :func:`random_printer_dict` drawn from
    ``self.np_random``. The resonance test's noise also comes from ``self.np_random``, so a seeded
    reset reproduces the episode exactly.

    ## Episode End
    One-shot: every ``step`` returns ``terminated=True`` (no truncation, no TimeLimit).

    ## Arguments
    ``gymnasium.make("ringtune/TuneFixed-v0", printer=None, job=None, ...)``:

    | argument | default | meaning |
    |---|---|---|
    | ``printer`` | None | Printer, TOML path or embedded name (fixed env); None = default printer |
    | ``randomize`` | False (True for Tune-v0) | draw a new printer every reset |
    | ``job`` | None | G-code path/text or parsed job; None = built-in test print |
    | ``firmware`` | "klipper" | target firmware (flavour of the shapers) |
    | ``shapers`` | all of the firmware's | shaper types to choose among |
    | ``per_axis`` | True | separate X/Y shaper settings |
    | ``tune_accel`` | False | the action also sets the acceleration |
    | ``freq_anchor`` | "absolute" | "absolute" or "peak": how the F entries decode (see Action Space) |
    | ``freq_limit_gate`` | False | frequency limit off for the lower half of its entry |
    | ``accel_anchor`` | "absolute" | "absolute" or "model": how the acceleration entry decodes (see Observation Space) |
    | ``weights`` | :data:`ringtune.envs.judgement.DEFAULT_WEIGHTS` | reward weights ``time``, ``worse`` (missing keys take the default) |
    | ``judgement`` | :data:`ringtune.envs.judgement.JUDGEMENT` | resolution and constraints of the judgement (missing keys take tune's default) |
    | ``freq_margin`` | 0.0 | also judge on the printer with its resonances this fraction lower and higher, damping ×0.75 (tune: 0.05) |
    | ``step_loss_penalty`` | 10.0 | subtracted when the motor loses steps |
    | ``n_bins`` | 24 | spectrum bins per axis |
    | ``spectrum_range`` | (10, 160) | Hz covered by the bins |
    | ``observe_metrics`` | True | evaluate the starting configuration at reset (one more evaluation) |
    | ``start_action`` | None | the starting configuration as an action (decoded on each printer's peaks); None = shaping off |
    | ``backend`` | "mujoco" | physics backend, "mujoco" or "lti" |
    | ``render_mode`` | None | None or "rgb_array" (the spectra and the configuration as an image) |

    ## Info
    ``reset``: ``printer`` (name), ``baseline_print_time_s``, ``peaks_hz`` (X, Y), ``accel_anchor``
    (mm/s²). ``step``: also ``config`` (TuneConfig dict) and ``metrics`` (Metrics dict).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1}

    def __init__(self, printer=None, *, randomize: bool = False, job=None, firmware: str = "klipper",
                 shapers: tuple[str, ...] | None = None, per_axis: bool = True, tune_accel: bool = False,
                 freq_anchor: str = "absolute", freq_limit_gate: bool = False, accel_anchor: str = "absolute",
                 weights: dict | None = None, step_loss_penalty: float = 10.0, n_bins: int = 24,
                 spectrum_range: tuple[float, float] = (10.0, 160.0), observe_metrics: bool = True,
                 start_action=None, backend: str = "mujoco", render_mode: str | None = None,
                 judgement: dict | None = None, freq_margin: float = 0.0):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise RingtuneError(f"render_mode must be None or 'rgb_array', not {render_mode!r}", "render_mode")
        self.render_mode = render_mode
        self.base_printer = resolve_printer(printer)
        self.randomize = bool(randomize)
        self.job = job
        shapers = checked_shapers(firmware, shapers)
        check_anchors(freq_anchor, accel_anchor, tune_accel and observe_metrics)
        self.spec_ = ActionSpec(firmware=firmware, shapers=tuple(shapers), per_axis=per_axis,
                                tune_accel=tune_accel, freq_anchor=freq_anchor,
                                freq_limit_gate=bool(freq_limit_gate), accel_anchor=accel_anchor)
        self.weights = over_defaults(weights, DEFAULT_WEIGHTS, "reward weights", "weights")
        self.step_loss_penalty = float(step_loss_penalty)
        self.judgement = over_defaults(judgement, JUDGEMENT, "judgement keys", "judgement")
        if not 0 <= float(freq_margin) < 1:
            raise RingtuneError(f"must be in [0, 1), not {freq_margin}", "freq_margin")
        self.freq_margin = float(freq_margin)
        self.baseline_metrics_: Metrics | None = None
        self._baseline_key = None
        self.n_bins = int(n_bins)
        self.spectrum_range = (float(spectrum_range[0]), float(spectrum_range[1]))
        self.observe_metrics = bool(observe_metrics)
        self.backend = backend
        n = self.spec_.size
        self.start_action = None if start_action is None else checked_start_action(start_action, self.spec_)
        self.start_metrics_: Metrics | None = None
        self.action_space = spaces.Box(-1.0, 1.0, (n,), np.float32)
        self._n_peak_obs = 2 if freq_anchor == "peak" else 0
        self._n_accel_obs = 1 if accel_anchor == "model" else 0
        self.observation_space = spaces.Box(
            -1.0, 1.0, (2 * self.n_bins + n + N_METRICS + self._n_peak_obs + self._n_accel_obs,), np.float32)
        self.accel_anchor_ = self.spec_.accel_start
        self.peaks_ = (50.0, 50.0)
        self.printer = self.base_printer
        self._spectra = np.zeros(2 * self.n_bins, np.float32)
        self._config_obs = np.zeros(n, np.float32)
        self._metrics_obs = np.zeros(N_METRICS, np.float32)
        self._baseline = 1.0
        self.config = TuneConfig(firmware=firmware, shaper_x="none", shaper_y="none")

    # -- helpers ---------------------------------------------------------------------------------
    def _spectrum(self) -> np.ndarray:
        spectra = {axis: resonance_test(self.printer, axis, rng=self.np_random) for axis in ("x", "y")}
        self.peaks_ = spectrum_peaks(spectra, self.spectrum_range)
        return spectrum_features(spectra, self.n_bins, self.spectrum_range)

    def observe_measured(self, spectra: dict) -> np.ndarray:
        """The reset observation for measured resonance PSDs ``{"x": (freqs, psd), …}`` (a missing
        axis takes the other's): their spectrum features and peaks, and the starting configuration
        as :meth:`reset` makes it (``start_action`` decoded on those peaks, else shaping off). With
        ``observe_metrics`` its metrics are those on this env's printer, which should then be a
        model of the measured one (e.g. identified from the same spectra). Sets ``peaks_`` so that
        :meth:`decode` anchors on them."""
        self.printer = self.base_printer
        self._baseline = planned_job(self.printer, self.job, None).print_time
        self._spectra = spectrum_features(spectra, self.n_bins, self.spectrum_range)
        self.peaks_ = spectrum_peaks(spectra, self.spectrum_range)
        self.observe_start()
        return self._obs()

    def decode(self, action) -> TuneConfig:
        """:func:`decode_action` with this env's spec, the current printer's peaks and acceleration anchor."""
        return decode_action(action, self.spec_, self.peaks_, self.accel_anchor_)

    def encode(self, config: TuneConfig) -> np.ndarray:
        """:func:`encode_config` with this env's spec, the current printer's peaks and acceleration anchor."""
        return encode_config(config, self.spec_, self.peaks_, self.accel_anchor_)

    def _metrics_vector(self, m: Metrics) -> np.ndarray:
        def sq(v, s):
            v = max(float(v), 0.0)
            return v / (v + s)

        return np.asarray([
            sq(m.print_time_s / self._baseline, METRIC_SCALES["time_ratio"]),
            sq(m.path_error_mm, METRIC_SCALES["path_error_mm"]),
            sq(m.overshoot_mm, METRIC_SCALES["overshoot_mm"]),
            sq(m.ringing_mm, METRIC_SCALES["ringing_mm"]),
            sq(m.peak_accel, self.printer.limits.accel),
            float(m.step_loss),
            sq(m.motor_load, 1.0),
        ], dtype=np.float32)

    def _obs(self) -> np.ndarray:
        parts = [self._spectra, self._config_obs, self._metrics_obs]
        if self._n_peak_obs:
            parts.append(peak_features(self.peaks_, self.spectrum_range))
        if self._n_accel_obs:
            lo, hi = self.spec_.accel_range
            parts.append(log_position([min(max(self.accel_anchor_, lo), hi)], lo, hi).astype(np.float32))
        return np.concatenate(parts).astype(np.float32)

    def cost(self, m: Metrics) -> float:
        """``tune``'s judgement of metrics ``m`` on the current printer against its baseline (see
        the class docstring; :func:`ringtune.envs.judgement.judged_cost`)."""
        return judged_cost(m, self.baseline_metrics_, self._baseline, self.weights, self.step_loss_penalty,
                           self.judgement)

    def reward(self, m: Metrics) -> float:
        """The reward of metrics ``m`` on the current printer: −:meth:`cost`."""
        return -float(self.cost(m))

    def evaluate(self, config: TuneConfig) -> Metrics:
        """``config`` judged as ``tune`` judges it: the worst of the printer and, with
        ``freq_margin``, its detuned twins (:func:`ringtune.envs.evaluate.evaluate_many`)."""
        return evaluate_many([config], self.printer, self.job, backend=self.backend, freq_margin=self.freq_margin)[0]

    def baseline_config(self) -> TuneConfig:
        """What every configuration is judged against on this printer (:func:`ringtune.envs.judgement.baseline_config`)."""
        return baseline_config(self.peaks_, self.spec_.firmware, self.printer.limits.accel)

    def _judge_baseline(self) -> None:
        """Evaluate the baseline on the current printer and peaks (``baseline_metrics_``; once per both)."""
        key = (self.printer, tuple(self.peaks_))
        if self._baseline_key is not None and key[0] is self._baseline_key[0] and key[1] == self._baseline_key[1]:
            return
        try:
            self.baseline_metrics_ = self.evaluate(self.baseline_config())
        except RingtuneError:        # a baseline the firmware cannot run: judged on time and constraints only
            self.baseline_metrics_ = None
        self._baseline_key = key

    def _draw_printer(self, attempts: int = 20):
        """A random printer whose linear model can be built (a draw on which the slip model's
        solver fails numerically, ``LinAlgError``, is replaced by the next draw of the same stream)."""
        for _ in range(attempts):
            printer = printer_from_dict(random_printer_dict(self.np_random, self.base_printer.to_dict()),
                                        "random printer")
            try:
                linear_system(printer)
            except (np.linalg.LinAlgError, FloatingPointError):
                continue
            return printer
        raise RingtuneError(f"{attempts} random printers in a row had no solvable model", "randomize")

    # -- gymnasium API ---------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)

        if self.randomize:
            self.printer = self._draw_printer()
        else:
            self.printer = self.base_printer
        self._baseline = planned_job(self.printer, self.job, None).print_time
        self._spectra = self._spectrum()
        options = options or {}
        start = options.get("config")
        if isinstance(start, dict):
            start = TuneConfig.from_dict(start, "options['config']")
        self.observe_start(config=start)
        return self._obs(), self._info()

    def observe_start(self, peaks=None, config: TuneConfig | None = None) -> None:
        """Make the starting configuration current (``config``, else ``start_action`` decoded on
        the peaks, else shaping off; ``peaks`` (X, Y) Hz replace ``peaks_`` first). With
        ``observe_metrics`` evaluate it on the current printer (``start_metrics_``; a configuration
        the firmware rejects shows zeros) and, with ``accel_anchor="model"``, set the acceleration
        anchor from those metrics."""
        if peaks is not None:
            self.peaks_ = (float(peaks[0]), float(peaks[1]))
        self._judge_baseline()
        self.accel_anchor_ = self.spec_.accel_start
        if config is None:
            config = (self.decode(self.start_action) if self.start_action is not None
                      else TuneConfig(firmware=self.spec_.firmware, shaper_x="none", shaper_y="none"))
        self.config = config
        self.start_metrics_ = None
        self._metrics_obs = np.zeros(N_METRICS, np.float32)
        if self.observe_metrics:
            try:
                self.start_metrics_ = self.evaluate(config)
            except RingtuneError:
                pass
            else:
                self._metrics_obs = self._metrics_vector(self.start_metrics_)
                if self.spec_.accel_anchor == "model":
                    self.accel_anchor_ = model_accel(self.printer, self.job, config, self.start_metrics_,
                                                     self.cost, self.spec_.accel_range)
        self._config_obs = self.encode(config)

    def step(self, action):
        config = self.decode(action)
        info: dict[str, Any] = {}
        try:
            m = self.evaluate(config)
            r = self.reward(m)
            info["metrics"] = m.to_dict()
            self._metrics_obs = self._metrics_vector(m)
        except RingtuneError as exc:  # a configuration the firmware cannot run
            r = -self.step_loss_penalty
            info["error"] = str(exc)
            self._metrics_obs = np.zeros(N_METRICS, np.float32)
        self.config = config
        self._config_obs = self.encode(config)
        info["config"] = config.to_dict()
        return self._obs(), r, True, False, {**self._info(), **info}

    def _info(self) -> dict:
        return {"printer": self.printer.name, "baseline_print_time_s": self._baseline,
                "baseline_config": self.baseline_config().to_dict(),
                "peaks_hz": tuple(self.peaks_), "accel_anchor": self.accel_anchor_}

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        matplotlib.use("Agg")
        fig = Figure(figsize=(4, 3), dpi=80)
        canvas = FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        lo, hi = self.spectrum_range
        centres = lo + (np.arange(self.n_bins) + 0.5) * (hi - lo) / self.n_bins
        ax.plot(centres, self._spectra[:self.n_bins], label="X")
        ax.plot(centres, self._spectra[self.n_bins:], label="Y")
        c = self.config
        ax.set_title(f"{c.shaper_x} {c.freq_x:.0f} Hz / {c.shaper_y} {c.freq_y:.0f} Hz", fontsize=9)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("PSD (1 + log10/3)")
        ax.legend(fontsize=8)
        canvas.draw()
        return np.asarray(canvas.buffer_rgba())[:, :, :3].copy()
