"""One record per target firmware: what it has, what it accepts, how it is spoken to.

Every module that needs a fact about a firmware reads it here: ``TuneConfig`` (which firmware names
exist and their shaper formulas), the search space (one shaper for all axes or not), the dialects
and push (ranges, precision, commands), the read-back parser (report format). Facts and their
sources: ``shared/reference/firmware.md`` (§1.5 Klipper, §2 Marlin, §3 RRF, §4 Prusa); the
acceleration commands from Klipper ``toolhead.py`` (``SET_VELOCITY_LIMIT``), Marlin
``M200-M205.cpp`` (``M204 P``, report ``  M204 P<a> R<a> T<a>``) and RRF ``Move.cpp`` (``M204 P``,
report ``Maximum printing acceleration <a>, maximum travel acceleration <a>``); the per-axis caps
from Marlin ``M201`` (report ``  M201 X<a> Y<a> ...``), RRF ``M201`` and Kalico's limited_*
kinematics (``klippy/kinematics/limited_corexy.py``, ``limited_cartesian.py``: ``max_x_accel``,
``max_y_accel``; ``toolhead.py``: ``SET_VELOCITY_LIMIT X_ACCEL= Y_ACCEL=``, reported as
``max_x_accel: ...`` while ``[danger_options] log_velocity_limit_changes`` is on, its default);
Marlin's build-time ``SHAPING_MIN_FREQ`` (``stepper.h``); what persists across a restart
(``reference/firmware.md`` §1.5, §2, §3.5, §4).

A :class:`Span` is a range the firmware accepts together with the number of decimals a value is
sent (and reported) with. A value that would round to another one at that precision is refused
rather than changed (0.0004 Hz is not "0", which would turn shaping off): "another one" is a sent
value outside the range or more than :data:`ROUNDING_TOLERANCE` away from the given one, the
resolution tune and recommend write values with (0.1 Hz at 20 Hz). Closer than that, the value is
sent at the firmware's precision and the export says so.

Plain data (frozen dataclasses and a dict): ``hardware`` may import it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.shapers import REGISTRY, available_shapers, get_shaper


#: largest relative change rounding to a firmware's precision may make before the value is refused
ROUNDING_TOLERANCE = 0.005


@dataclass(frozen=True)
class Span:
    """Values a firmware accepts: ``[lo, hi]`` (``(lo, hi]`` when ``lo_open``), sent with ``decimals``
    digits after the point. ``why`` says where a bound comes from when it is not the firmware's
    own check (shown with a refusal)."""

    lo: float
    hi: float
    decimals: int
    lo_open: bool = False
    why: str = ""

    def text(self, unit: str = "") -> str:
        """The range as printed in refusals: ``[4, 1000] Hz``, ``(0, 100] Hz``."""
        lo = f"{self.lo:.2f}".rstrip("0").rstrip(".") if self.lo != int(self.lo) else f"{self.lo:g}"
        return f"{'(' if self.lo_open else '['}{lo}, {self.hi:g}]" + (f" {unit}" if unit else "")

    def contains(self, value: float) -> bool:
        return (math.isfinite(value) and value <= self.hi
                and (value > self.lo if self.lo_open else value >= self.lo))

    def sent(self, value: float) -> float:
        """``value`` as sent: rounded to ``decimals`` digits."""
        return round(value, self.decimals)

    def changes(self, value: float) -> bool:
        """True if sending ``value`` changes it into another one (see module docstring)."""
        got = self.sent(value)
        return not self.contains(got) or abs(got - value) > ROUNDING_TOLERANCE * abs(value)


@dataclass(frozen=True)
class Firmware:
    """What one target firmware is.

    Attributes:
        name: the name configs and ``--firmware`` use (``klipper``, ``rrf35``, ...).
        title: human name with version (``RepRapFirmware 3.5``).
        flavor: its shaper formulas in :mod:`ringtune.shaping.shapers` (hence its shapers, their
            parameters and maximum damping).
        family: command dialect and report format (``klipper``, ``rrf``, ``marlin``,
            ``marlin-ftm``, ``prusa``).
        protocol: the serial link it speaks (``klipper`` plain lines; ``marlin``/``rrf``
            numbered and checksummed).
        one_shaper: one shaper (type, F, S) for all axes (RepRapFirmware).
        freq: shaper frequency, Hz.
        damping: damping ratio (the shaper's own maximum also applies).
        freq_limit: the firmware has an XY direction-change frequency limit (Marlin ``M201 F S``);
            elsewhere ``ringtune limit`` applies it to the G-code.
        accel_set: command that sets the tuned acceleration (``{a}`` = mm/s²): printing and, where
            the firmware keeps it apart, travel (``M204 P T``: the tuned acceleration is what every
            XY move was planned with; Marlin's retractions keep ``M204 R``).
        accel_report: command whose reply reports it.
        accel: printing acceleration, mm/s².
        comment: the G-code comment character the firmware reads.
        save: lines that persist shaping settings from G-code (empty: they belong in a config file).
        config_file: where settings go when they cannot be saved from G-code, or None.
        native_names: (canonical name, the firmware's own name) where they differ (RRF ``ei2``).
        axis_accel_set: command that sets the per-axis X/Y acceleration caps (``{x}``, ``{y}`` in
            mm/s²), empty if the firmware has none (mainline Klipper: one ``max_accel``).
        axis_accel_report: command whose reply reports them.
        axis_accel: the caps' range and precision (Marlin keeps M201 as whole mm/s²).
        axis_accel_config: the config-file keys of those caps (``max_{ax}_accel`` on Kalico's
            limited_* kinematics), empty if they are set by G-code.
        axis_accel_kinematics: kinematics on which the per-axis caps exist (empty: all).
        accel_roles: the accelerations the firmware keeps apart, besides per-axis caps: ``print``
            (extruding moves), ``travel`` (non-extruding), ``retract`` (E-only moves).
        persists: what of the tuned settings survives a restart, and how.
        build_min_freq: the lowest shaper frequency (Hz) a stock build handles as it should, where
            the build (not a G-code check) sets it (Marlin classic: SHAPING_MIN_FREQ); 0 = none.
        build_min_freq_why: what it is and what happens below it.
        e_timing: the extruder under input shaping (seed 002; :mod:`ringtune.shaping.e_timing`):
            ``shaped`` with X/Y's impulses, ``delayed`` by the shaped axes' lag, or ``neither``.
        xy_delay: how the shaped X/Y are delayed against the firmware's own (extruder) clock:
            ``centred`` (impulses centred, no lag on average), ``causal`` (each axis by its
            centroid ΣAᵢTᵢ) or ``largest`` (every shaped axis by the largest centroid).
        e_sync: how to make the extruder follow X/Y where the firmware can and does not by
            default ("" where it already does or cannot).
        e_sync_timing: the ``e_timing`` that ``e_sync`` gives ("" without it).
        e_source: where ``e_timing`` and ``xy_delay`` were read (file and function).
        junctions: the junction rules its planner can corner by (``scv``: Klipper's
            square_corner_velocity; ``jd``: junction deviation; ``jerk``: classic jerk, RRF's M566).
    """

    name: str
    title: str
    flavor: str
    family: str
    protocol: str
    one_shaper: bool
    freq: Span
    damping: Span
    freq_limit: bool
    accel_set: str
    accel_report: str
    accel: Span
    comment: str = ";"
    save: tuple[str, ...] = ()
    config_file: str | None = None
    native_names: tuple[tuple[str, str], ...] = ()
    axis_accel_set: str = ""
    axis_accel_report: str = ""
    axis_accel: Span = Span(1.0, 1e6, 0)
    axis_accel_config: str = ""
    axis_accel_kinematics: tuple[str, ...] = ()
    accel_roles: tuple[str, ...] = ("print",)
    persists: str = ""
    build_min_freq: float = 0.0
    build_min_freq_why: str = ""
    e_timing: str = "neither"
    xy_delay: str = "centred"
    e_sync: str = ""
    e_sync_timing: str = ""
    e_source: str = ""
    junctions: tuple[str, ...] = ("jd", "jerk")

    @property
    def shapers(self) -> tuple[str, ...]:
        """Canonical names of the shapers it has (``none`` included), from its flavour's formulas."""
        return available_shapers(self.flavor)

    def native(self, base: str) -> str:
        """The firmware's own name of canonical shaper ``base`` (RRF: ``2hump_ei`` is ``ei2``)."""
        return dict(self.native_names).get(base, base)

    def max_damping(self, base: str) -> float:
        """Largest damping ratio of shaper ``base`` here: the firmware's and the shaper's own limit."""
        return min(REGISTRY[self.flavor][base][2], self.damping.hi)

    def check_shaper(self, name: str, freq: float, damping: float, where: str) -> None:
        """``ringtune shaper``'s own check of a shaper string at ``freq`` Hz and ``damping`` (its
        parameters: unknown ones, Klipper's mzv ``n >= 3``, the ``v_tol`` range, ...)."""
        get_shaper(name, freq, damping, self.flavor, where=where)

    def junction_note(self, junction: str) -> str:
        """"" where the firmware corners by ``junction`` (a printer description's ``[limits]
        junction``), else what that means, in one sentence."""
        if junction in self.junctions:
            return ""
        own = " or ".join(JUNCTION_NAMES[j] for j in self.junctions)
        return (f"the printer description corners by {JUNCTION_NAMES.get(junction, junction)} ([limits] junction = "
                f"\"{junction}\"), which {self.title} does not have (it corners by {own}): corners and print time "
                f"are planned that way, not as {self.title} would (the job's own acceleration commands are read as "
                f"{self.title} reads them); describe the printer with its own (`ringtune "
                "printer from-klipper|from-marlin|from-rrf` reads it)")

    @staticmethod
    def named(name: str, where: str = "firmware") -> "Firmware":
        """The record of ``name`` (case-insensitive: ``Klipper`` is ``klipper``); a refusal naming
        the firmwares there are otherwise."""
        key = name.strip().lower() if isinstance(name, str) else name
        if key not in FIRMWARES:
            raise RingtuneError(f"firmware must be one of {', '.join(FIRMWARES)}, not {name!r}", where)
        return FIRMWARES[key]


def job_reading(name) -> dict:
    """How the firmware ``name`` (a key of :data:`FIRMWARES`; None or unknown: not known) reads a
    job's limit commands, as :class:`ringtune.shaping.planner.MachineLimits` fields:
    RepRapFirmware takes M203 in mm/min (Marlin: mm/s); Marlin and Prusa have no M566 (RRF's
    jerk), only M205 X Y; Klipper and Kalico read one acceleration and no M201/M203
    (``klipper_reading``); each family cuts G2/G3 into its own segments (``arc_firmware``). Not known:
    M203 in mm/s, M566 read, the reading and the arcs the junction rule implies."""
    fw = FIRMWARES.get(str(name or "").strip().lower())
    family = fw.family if fw else None
    return {"m203_per_minute": family == "rrf", "reads_m566": family not in ("marlin", "marlin-ftm", "prusa"),
            "klipper_reading": None if fw is None else family == "klipper",
            "arc_firmware": None if fw is None else _ARC_FAMILY.get(family, family)}


#: whose arcs a firmware family's are (:attr:`ringtune.shaping.planner.MachineLimits.arc_firmware`)
_ARC_FAMILY = {"marlin-ftm": "marlin"}


#: each junction rule in words
JUNCTION_NAMES = {"scv": "Klipper's square-corner velocity", "jd": "Marlin's junction deviation",
                  "jerk": "classic jerk"}
_KLIPPER_ACCEL = Span(1.0, 1e6, 3, why="Klipper takes any ACCEL > 0")
_KLIPPER_FREQ = Span(1.0, 1000.0, 3, why="ringtune's bound: Klipper takes any F > 0, but below 1 Hz one shaper "
                                         "outlasts half a second and delays every step by that")
_M204_2 = Span(1.0, 1e6, 2)
_RRF_ACCEL = Span(1.0, 1e6, 1)
_RRF35_FREQ = Span(750000.0 / 131070.0, 1000.0, 2, why="Duet 3: StepClockRate / (2·65535)")
_RRF_NAMES = (("2hump_ei", "ei2"), ("3hump_ei", "ei3"))      # InputShaperType names
#: Marlin's M201 per-axis maxima (mm/s²); RRF's M201 takes the same letters and unit
_M201_XY = "M201 X{x} Y{y}"
#: Marlin's max_acceleration_mm_per_s2 is a uint32_t: M201 keeps whole mm/s²
_M201_SPAN = Span(1.0, 1e6, 0, why="Marlin stores M201 as whole mm/s²")
#: Kalico's limited_cartesian / limited_corexy kinematics (klippy/kinematics/limited_*.py)
KALICO_LIMITED = ("limited_cartesian", "limited_corexy", "limited_corexz")

_KLIPPER_KEEPS = ("nothing set by SET_INPUT_SHAPER or SET_VELOCITY_LIMIT survives a restart: only "
                  "printer.cfg does ([input_shaper], and max_accel in [printer]); SHAPER_CALIBRATE + "
                  "SAVE_CONFIG writes shaper_type and shaper_freq, never damping_ratio")
_RRF_KEEPS = ("nothing set by G-code survives a restart (M500 stores neither M593 nor M201/M204): "
              "the lines belong in config.g")
_MARLIN_KEEPS = "M500 stores the shaper, M201 and M204 in EEPROM (EEPROM_SETTINGS builds)"
#: Marlin classic (stepper.h): SHAPING_MIN_FREQ defaults to the lower of SHAPING_FREQ_X/Y (40 Hz in
#: a stock Configuration_adv.h) and sizes the echo buffer (max step rate / SHAPING_MIN_FREQ / 2 + 3);
#: below it the buffer fills at high step rates and stepper.cpp applies echoes early
_MARLIN_MIN_FREQ_WHY = ("a stock build's SHAPING_MIN_FREQ (the lower of SHAPING_FREQ_X/Y, 40 Hz by default), "
                        "which sizes the echo buffer: below it, at high step rates, Marlin applies the "
                        "echoes early and the shaping no longer cancels the ringing")

#: extruder timing facts per firmware family (Firmware.e_timing, xy_delay, e_sync, e_sync_timing,
#: e_source); read in the firmwares' sources, see each e_source
_E_KLIPPER = dict(
    e_timing="neither", xy_delay="centred",
    e_source="Klipper klippy/chelper/kin_shaper.c init_shaper/shift_pulses (impulses shifted so that "
             "Σaᵢtᵢ = 0; only x, y, z are shaped); kin_extruder.c (the extruder is not shaped, only "
             "smoothed by pressure advance)")
_E_KALICO = dict(
    e_timing="neither", xy_delay="centred",
    e_sync="set enabled_extruders: extruder in [input_shaper] (Kalico's \"synchronisation of extruder "
           "motion with the input shaper\"; commented out in its example configuration)",
    e_sync_timing="shaped",
    e_source="Kalico klippy/extras/input_shaper.py InputShaper.__init__ (config.getlist('enabled_extruders', "
             "[]): no extruder is shaped unless listed); otherwise Klipper's kin_shaper.c (centred impulses)")
_E_RRF = dict(
    e_timing="shaped", xy_delay="causal",
    e_source="RepRapFirmware src/Movement/Move.cpp Move::AddLinearSegments (\"taking account of "
             "possible input shaping. This is used by linear axes and by extruders\"; causal "
             "impulses, no centring); 3.4 reshapes each move's acceleration phases, which all its "
             "drives follow")
_E_MARLIN = dict(
    e_timing="neither", xy_delay="causal",
    e_source="seed 002, by the author of Marlin's classic input shaping: the shaped axes' steps are "
             "diverted through ShapingQueue and echoed after the pulse (Stepper::pulse_phase_isr, "
             "Stepper::shaping_isr); the non-shaped axes are not rescheduled (\"nothing has been done "
             "in Marlin yet\"), so the extruder leads X/Y by their lag")
_E_MARLIN_FTM = dict(
    e_timing="neither", xy_delay="largest",
    e_sync="build with FTM_SHAPER_E (Configuration_adv.h: \"Required to synchronize extruder with "
           "XYZ\") and keep axis synchronisation on (its default)",
    e_sync_timing="delayed",
    e_source="Marlin src/module/ft_motion.cpp FTMotion::calc_traj_point (with axis_sync_enabled, the "
             "default, every shaped axis is delayed to the largest centroid; the extruder is in the "
             "shaped set only with FTM_SHAPER_E, which Configuration_adv.h leaves off); "
             "ft_motion/shaping.h refresh_largest_delay_samples")
_E_PRUSA = dict(
    e_timing="neither", xy_delay="centred",
    e_source="Prusa-Firmware-Buddy lib/Marlin/Marlin/src/module/prusa/input_shaper.cpp "
             "input_shaper_step_generator_init (X, Y, Z only: \"Input shaper isn't supported on this "
             "axis\"); pulses centred as Klipper's (init_input_shaper_pulses)")

FIRMWARES: dict[str, Firmware] = {f.name: f for f in (
    Firmware("klipper", "Klipper", "klipper", "klipper", "klipper", False, _KLIPPER_FREQ,
             Span(0.0, 0.99, 6), False, "SET_VELOCITY_LIMIT ACCEL={a}", "SET_VELOCITY_LIMIT",
             _KLIPPER_ACCEL, ";", (), "printer.cfg", persists=_KLIPPER_KEEPS, junctions=("scv",), **_E_KLIPPER),
    # Kalico (the Klipper fork formerly Danger Klipper): Klipper's toolhead, shapers and commands, plus
    # per-axis acceleration caps on its limited_* kinematics: [printer] max_x_accel / max_y_accel,
    # set at run time by SET_VELOCITY_LIMIT X_ACCEL= Y_ACCEL= (reported as max_x_accel: ...).
    # Its shapers are its flavour's: Klipper's closed forms of before 2025 and Kalico's continuous
    # smoothers (smooth_zv ... smooth_si, set by SHAPER_TYPE_X= with SMOOTHER_FREQ_X=).
    Firmware("kalico", "Kalico", "kalico", "klipper", "klipper", False, _KLIPPER_FREQ,
             Span(0.0, 0.99, 6), False, "SET_VELOCITY_LIMIT ACCEL={a}", "SET_VELOCITY_LIMIT",
             _KLIPPER_ACCEL, ";", (), "printer.cfg",
             axis_accel_set="SET_VELOCITY_LIMIT X_ACCEL={x} Y_ACCEL={y}", axis_accel_report="SET_VELOCITY_LIMIT",
             axis_accel=_KLIPPER_ACCEL, axis_accel_config="max_{ax}_accel",
             axis_accel_kinematics=KALICO_LIMITED,
             persists=_KLIPPER_KEEPS.replace("max_accel in [printer]",
                                             "max_accel, max_x_accel, max_y_accel in [printer]"),
             junctions=("scv",), **_E_KALICO),
    Firmware("rrf", "RepRapFirmware 3.6", "rrf", "rrf", "rrf", True, Span(4.0, 1000.0, 2, why="RRF 3.6's minimum"),
             Span(0.0, 0.99, 3), False, "M204 P{a} T{a}", "M204", _RRF_ACCEL, ";", (), "config.g", _RRF_NAMES,
             axis_accel_set=_M201_XY, axis_accel_report="M201", axis_accel=_RRF_ACCEL,
             accel_roles=("print", "travel"), persists=_RRF_KEEPS, junctions=("jerk",), **_E_RRF),
    Firmware("rrf35", "RepRapFirmware 3.5", "rrf35", "rrf", "rrf", True, _RRF35_FREQ,
             Span(0.0, 0.99, 3), False, "M204 P{a} T{a}", "M204", _RRF_ACCEL, ";", (), "config.g", _RRF_NAMES,
             axis_accel_set=_M201_XY, axis_accel_report="M201", axis_accel=_RRF_ACCEL,
             accel_roles=("print", "travel"), persists=_RRF_KEEPS, junctions=("jerk",), **_E_RRF),
    Firmware("rrf34", "RepRapFirmware 3.4", "rrf35", "rrf", "rrf", True, _RRF35_FREQ,
             Span(0.0, 0.99, 3), False, "M204 P{a} T{a}", "M204", _RRF_ACCEL, ";", (), "config.g", _RRF_NAMES,
             axis_accel_set=_M201_XY, axis_accel_report="M201", axis_accel=_RRF_ACCEL,
             accel_roles=("print", "travel"), persists=_RRF_KEEPS, junctions=("jerk",), **_E_RRF),
    Firmware("marlin", "Marlin (classic input shaping)", "marlin", "marlin", "marlin", False,
             Span(0.0, 1000.0, 2, lo_open=True, why="Marlin's own minimum F depends on the board"),
             Span(0.0, 1.0, 3), True, "M204 P{a} T{a}", "M204", _M204_2, ";", ("M500",),
             axis_accel_set=_M201_XY, axis_accel_report="M201", axis_accel=_M201_SPAN,
             accel_roles=("print", "retract", "travel"), persists=_MARLIN_KEEPS,
             build_min_freq=40.0, build_min_freq_why=_MARLIN_MIN_FREQ_WHY, **_E_MARLIN),
    Firmware("marlin-ftm", "Marlin FT_MOTION", "marlin-ftm", "marlin-ftm", "marlin", False,
             Span(10.0, 500.0, 2, why="FTM_MIN_SHAPE_FREQ..FTM_FS/2"), Span(0.01, 1.0, 3), True,
             "M204 P{a} T{a}", "M204", _M204_2, ";", ("M500",),
             axis_accel_set=_M201_XY, axis_accel_report="M201", axis_accel=_M201_SPAN,
             accel_roles=("print", "retract", "travel"),
             persists=_MARLIN_KEEPS.replace("the shaper", "M493"), **_E_MARLIN_FTM),
    Firmware("prusa", "Prusa-Firmware-Buddy", "klipper-legacy", "prusa", "marlin", False,
             Span(10.0, 100.0, 2, why="it clamps other values to 10-100 Hz"), Span(0.0, 0.99, 3), False,
             "M204 P{a} T{a}", "M204", _M204_2, ";", ("M593 W",),
             axis_accel_set=_M201_XY, axis_accel_report="M201", axis_accel=_M201_SPAN,
             accel_roles=("print", "retract", "travel"),
             persists="M593 W stores the shaper; M201 and M204 last until restart", **_E_PRUSA),
)}
