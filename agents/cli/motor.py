"""``ringtune motor``: a stepper's force at the belt against speed, from its datasheet constants.

JSON keys (stable): ``motor`` (name), ``constants`` {``holding_torque_nm``, ``rated_current_a``,
``resistance_ohm``, ``inductance_h``, ``steps_per_revolution``}, ``run_current_a``, ``voltage_v``,
``rotation_distance_mm``, ``assumed`` (list of what was not given and what was used), ``force_n``
(list of [speed_mm_s, force_n]), ``corner_speed_mm_s``, ``half_force_speed_mm_s``, and with
``--mass``: ``mass_kg``, ``accel_mm_s2`` (list of [speed_mm_s, accel_mm_s2]: F(v)/mass), ``plot``.
"""

from __future__ import annotations


import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from ringtune.agents.cli.common import check_output_folder
from ringtune.agents.cli.options import VALUES, Value
from ringtune.envs.motor_report import motor_report
from ringtune.envs.motors import lookup_motor, unknown_motor_message
from ringtune.shaping.errors import RingtuneError

NAME = "motor"
DESCRIPTION = """\
The force a stepper motor can give at the belt as the belt speeds up, from the motor's datasheet
constants (the built-in table holds every motor of Klipper's autotune plugin, by the names Klipper
users write in [autotune_tmc stepper_x] motor:), the driver's run current and supply voltage, and the
belt travel per revolution. Physics: torque constant from holding torque and rated current, the
phase current the driver can still push against the winding's resistance, inductance and back-EMF
at each speed (see ringtune.envs.stepper).

The acceleration with --mass is F(v)/mass at each speed: the largest acceleration one motor can give
that mass while passing that speed, without the rotor's own inertia and friction (add the rotor's
reflected mass J/r² to --mass to count it). Values not given are said on stderr with what is used.

A motor the table does not know (or one whose datasheet differs) is given by its constants, the
same five as Klipper's [motor_constants NAME] section: --holding-torque, --rated-current,
--resistance, --inductance (and --steps-per-revolution, default 200).

examples:
  ringtune motor ldo-42sth48-2504ac
  ringtune motor fysetc-35hsh7402-24b-400a --holding-torque 0.42 --rated-current 1.5 \\
      --resistance 2.8 --inductance 0.0055 --run-current 0.7
  ringtune motor ldo-42sth40-1684ac --run-current 0.9 --voltage 24 --rotation-distance 40 --mass 0.8
  ringtune motor ldo-42sth48-2504ac --voltage 48 --plot force.png --json
"""

#: (flag, metavar, help) of the datasheet constants, in the order of the [motor] keys
CONSTANT_FLAGS = (
    ("--holding-torque", "NM", "holding torque, N·m at the rated current (max_current)"),
    ("--rated-current", "A", "rated (datasheet) current per phase, A (Klipper's max_current)"),
    ("--resistance", "OHM", "phase resistance, Ω"),
    ("--inductance", "H", "phase inductance, H (0.0036 for 3.6 mH)"),
    ("--steps-per-revolution", "N", "full steps per revolution: 200 (1.8°) or 400 (0.9°)"),
)
#: their [motor] keys (the options' destinations)
CONSTANT_KEYS = tuple(flag[2:].replace("-", "_") for flag, _, _ in CONSTANT_FLAGS)
#: what each constant must be
CONSTANT_VALUES = {"--holding-torque": Value("a torque", "N·m", 0.0), "--rated-current": VALUES["current"],
                   "--resistance": Value("a resistance", "Ω", 0.0), "--inductance": Value("an inductance", "H", 0.0),
                   "--steps-per-revolution": Value("a step count", "", 0.0)}


def add_arguments(parser) -> None:
    parser.add_argument("name", metavar="NAME", help="motor name as in Klipper's autotune plugin, "
                                                     "e.g. ldo-42sth48-2504ac")
    parser.add_argument("--run-current", metavar="A", type=VALUES["current"], default=None,
                        help="driver current, A RMS (Klipper run_current, M906); default rated/√2")
    parser.add_argument("--voltage", metavar="V", type=VALUES["voltage"], default=None,
                        help="driver supply voltage, V (default 24)")
    parser.add_argument("--rotation-distance", metavar="MM", type=VALUES["length"], default=None,
                        help="mm of belt per motor revolution (default 40: GT2 belt, 20-tooth pulley)")
    c = parser.add_argument_group("the motor's datasheet constants (Klipper's [motor_constants]): for a motor "
                                  "the table does not know, or to override the table's")
    for flag, meta, what in CONSTANT_FLAGS:
        c.add_argument(flag, metavar=meta, type=CONSTANT_VALUES[flag], default=None, help=what)
    parser.add_argument("--mass", metavar="KG", type=VALUES["mass"], default=None,
                        help="moving mass, kg: also report the acceleration the force allows")
    parser.add_argument("--plot", metavar="OUT.png", default=None, help="write the force–speed graph here")


def run(args, out) -> int:
    check_output_folder("--plot", args.plot)
    given = {key: getattr(args, key) for key in CONSTANT_KEYS if getattr(args, key) is not None}
    _check_known(args.name, given)
    report = motor_report(args.name, given, args.run_current, args.voltage, args.rotation_distance, args.mass)
    out.note(*report.notes)
    result = {**report.result, "plot": args.plot}
    if args.plot:
        _plot(args, report.drive, result)
    out.emit(result, _text(result, report.drive))
    return 0


def _check_known(name: str, given: dict) -> None:
    """A motor the table does not know needs its four datasheet constants."""
    if lookup_motor(name) is None:
        missing = [k for k in CONSTANT_KEYS[:4] if k not in given]
        if missing:
            raise RingtuneError(unknown_motor_message(name).rsplit("; give", 1)[0] + "; give its "
                                "constants: " + " ".join("--" + k.replace("_", "-") for k in missing))


def _text(r: dict, drive) -> str:
    c = r["constants"]
    lines = [f"{r['motor']}: {c['holding_torque_nm']:g} N·m holding at {c['rated_current_a']:g} A, "
             f"{c['resistance_ohm']:g} Ω, {c['inductance_h'] * 1e3:g} mH per phase, "
             f"{c['steps_per_revolution']} steps/rev",
             f"driven at {r['run_current_a']:.3g} A RMS from {r['voltage_v']:g} V, "
             f"{r['rotation_distance_mm']:g} mm of belt per revolution (pulley radius "
             f"{drive.radius * 1e3:.2f} mm)",
             "force at the belt (pull-out force of one motor, stepper physics):"]
    acc = dict((s, a) for s, a in r.get("accel_mm_s2", []))
    for s, f in r["force_n"]:
        extra = f"   {acc[s]:>8.0f} mm/s² for {r['mass_kg']:g} kg" if acc else ""
        lines.append(f"  {s:>5.0f} mm/s  {f:>7.1f} N{extra}")
    lines.append(f"full force up to {r['corner_speed_mm_s']:.0f} mm/s; half of it at "
                 f"{r['half_force_speed_mm_s']:.0f} mm/s")
    if acc:
        lines.append("mm/s² = force at that speed / mass (rotor inertia and friction not counted)")
    if r["plot"]:
        lines.append(f"graph written to {r['plot']}")
    return "\n".join(lines)


def _plot(args, drive, r: dict) -> None:
    matplotlib.use("Agg")
    top = max(1000.0, 2.0 * min(r["half_force_speed_mm_s"], 5000.0))
    v = np.linspace(0.0, top, 400)
    f = drive.force(v)
    fig, ax = plt.subplots(figsize=(9, 5))
    ax.plot(v, f, lw=2, label=f"{r['motor']}, {r['run_current_a']:.3g} A RMS, {r['voltage_v']:g} V")
    ax.axvline(r["half_force_speed_mm_s"], color="grey", ls=":", lw=1,
               label=f"half force at {r['half_force_speed_mm_s']:.0f} mm/s")
    ax.set_xlabel("belt speed, mm/s")
    ax.set_ylabel("force at the belt, N")
    ax.set_xlim(0, top)
    ax.set_ylim(0, 1.05 * float(f[0]))
    if args.mass:
        sec = ax.secondary_yaxis("right", functions=(lambda y: y / args.mass * 1e3,
                                                      lambda a: a * args.mass * 1e-3))
        sec.set_ylabel(f"acceleration for {args.mass:g} kg, mm/s²")
    ax.set_title(f"Pull-out force against speed (rotation distance {r['rotation_distance_mm']:g} mm)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize="small")
    fig.tight_layout()
    fig.savefig(args.plot, dpi=110)
    plt.close(fig)
