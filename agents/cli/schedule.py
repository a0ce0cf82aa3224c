"""``ringtune schedule``: a bed slinger's Y shaper frequency by layer, from the print's mass.

JSON keys (stable): ``firmware``, ``filament_diameter_mm``, ``filament_density_g_cm3``,
``filament_source`` ({``diameter_mm``, ``density_g_cm3``}: ``given``, ``the job's`` or ``default``),
``print_mass_g``, ``layers``, ``empty_mode_hz``, ``final_mode_hz``, ``scheduled`` (false: the mode
moves less than the band step, nothing is inserted, ``y_schedule`` and ``last_band`` are null),
``tuned_freq_y``, ``band_step``, ``bands`` (each:
``first_layer``, ``last_layer``, ``z_mm``, ``mass_g``, ``mode_hz``, ``freq_y``, ``accel``,
``prusa_rule_hz``, ``prusa_default_rule_hz``, ``commands``), ``y_schedule``, ``last_band``
(``first_layer``, ``last_layer``, ``z_mm``, ``z_top_mm``, ``mass_g``, ``mode_hz``, ``fixed``,
``scheduled`` and on Prusa ``prusa_default_rule``: {``freq_y``, ``freq_x``, ``accel``,
``ripple_mm``, ``corner_in_mm``, ``corner_out_mm``, ``print_time_s``}, ``measured_against``),
``notes``, ``output``, ``config_out``.
"""

from __future__ import annotations

from ringtune.agents.cli.common import (GCODE_JOB_HELP, check_gcode_output, check_output_folder, firmware_name,
                                        gcode_job, load_config)
from ringtune.agents.cli.options import VALUES
from ringtune.agents.tune.mass_check import schedule_job
from ringtune.agents.tune.mass_report import schedule_summary
from ringtune.agents.tune.mass_schedule import BAND_ACCEL, BAND_STEP
from ringtune.shaping.layers import FILAMENT_DENSITY_G_CM3, FILAMENT_DIAMETER_MM

NAME = "schedule"
DESCRIPTION = f"""\
On a bed slinger the print rides on the Y axis: as it grows, Y's modes fall as 1/√(moving mass)
and a Y shaper tuned on the empty bed drifts off them. This reads the job's extruded filament
(diameter and density stated, PLA by default), the mass on the bed at each layer, the printer
model's Y mode at that mass, and moves the config's freq_y with the mode: a new band of layers
wherever the mode has moved --band-step per cent. The job's last band of layers is simulated with
its mass on the bed at the fixed and at the scheduled frequency (ripple, corners and time, against
the commanded path).

-o writes the job with each band's line inserted at its first layer change, in the firmware's
form: Klipper SET_INPUT_SHAPER SHAPER_FREQ_Y=, Marlin M593 Y F, FT_MOTION M493 Y A, Prusa M74 W<g>
(the firmware moves Y by its own linear rule; ours is stated beside it), RepRapFirmware M593 F
(one shaper for every axis: what it costs X is said). Nothing else in the file changes.
--config-out writes the config with its y_schedule.

A lower shaper frequency smooths corners more at the same acceleration: where a band's shaper would
round corners more than 5 % beyond the tuned one (Klipper's smoothing estimate), its acceleration
is lowered until it does not, and the last band's corners are simulated to check it (held lower
until they round no more than the fixed frequency's) (--band-accel auto, the default; keep:
frequency only). The last-band table shows what that costs in time and gives in corners.

examples:
  ringtune schedule tall.gcode --config best.json -o tall_scheduled.gcode
  ringtune schedule tall.gcode --config best.json --firmware prusa --filament-density 1.27 --json
  ringtune schedule tall.gcode --config best.json --band-accel keep --config-out best_scheduled.json

defaults: the filament the job's slicer wrote in it (PrusaSlicer, SuperSlicer, OrcaSlicer, Simplify3D),
else {FILAMENT_DIAMETER_MM} mm of PLA at {FILAMENT_DENSITY_G_CM3} g/cm³; band step {BAND_STEP * 100:g} %.
"""

PARAMETER_FLAGS = {"diameter_mm": "--filament-diameter", "density_g_cm3": "--filament-density",
                   "step": "--band-step"}


def add_arguments(parser) -> None:
    parser.add_argument("gcode", metavar="JOB.gcode", type=gcode_job, help=f"the sliced job, {GCODE_JOB_HELP}")
    parser.add_argument("--config", metavar="C", required=True, help="TuneConfig JSON (tune's best.json)")
    parser.add_argument("--printer", metavar="P", help="printer TOML or embedded name (default: ender3)")
    parser.add_argument("--firmware", type=firmware_name, default=None,
                        help="write the lines for this firmware (default: the config's)")
    parser.add_argument("--filament-diameter", metavar="MM", type=VALUES["filament_diameter"], default=None,
                        help=f"filament diameter, mm (default: what the job's slicer wrote in it, else "
                             f"{FILAMENT_DIAMETER_MM})")
    parser.add_argument("--filament-density", metavar="G_CM3", type=VALUES["filament_density"], default=None,
                        help=f"filament density, g/cm³ (default: what the job's slicer wrote in it, else "
                             f"{FILAMENT_DENSITY_G_CM3}, PLA)")
    parser.add_argument("--band-step", metavar="PCT", type=VALUES["margin_percent"], default=BAND_STEP * 100,
                        help="start a new band where the Y mode has moved this many per cent "
                             f"(default {BAND_STEP * 100:g})")
    parser.add_argument("--band-accel", choices=BAND_ACCEL, default="auto",
                        help="auto: lower a band's acceleration where its lower shaper frequency would round "
                             "corners more than the tuned one (Klipper's smoothing estimate, checked on the "
                             "simulated last band); keep: never (default: auto)")
    parser.add_argument("--shaping-min-freq", metavar="HZ", type=VALUES["freq"], default=None,
                        help="your build's lowest shaper frequency (Marlin's SHAPING_MIN_FREQ; default: a "
                             "stock build's, 40 Hz on Marlin); a band below it runs at it")
    parser.add_argument("-o", "--output", metavar="OUT", help="write the job with the schedule's lines")
    parser.add_argument("--config-out", metavar="OUT.json", help="write the config with its y_schedule")


def run(args, out) -> int:
    check_gcode_output("--output", args.output)
    check_output_folder("--config-out", args.config_out)
    cfg = load_config(args.config, out)
    if args.firmware is not None:
        cfg.firmware = args.firmware
        cfg.validate()
    s = schedule_job(cfg, args.printer, args.gcode, diameter_mm=args.filament_diameter,
                     density_g_cm3=args.filament_density, step=args.band_step / 100.0,
                     band_accel=args.band_accel, min_freq=args.shaping_min_freq, output=args.output,
                     config_out=args.config_out)
    result = {**s.to_dict(), "output": args.output, "config_out": args.config_out}
    text = schedule_summary(s)
    for path, what in ((args.output, "job"), (args.config_out, "config")):
        if path:
            text += f"\n{what} written to {path}"
    out.emit(result, text)
    return 0
