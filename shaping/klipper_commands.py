"""The commands a Klipper (or Kalico) printer knows without a macro, and the job's others.

Klipper acts on the G-codes and extended commands its own modules register; any other command in a
job is a macro of the user's printer.cfg (``[gcode_macro PRINT_START]``), or, where none is defined,
answered with "Unknown command" and skipped. A macro's commands are not in the job: if it sets the
acceleration (``SET_VELOCITY_LIMIT``) or the input shaper, the printer runs the job otherwise than
it reads. :func:`macro_calls` finds those commands; :func:`macro_note` says so
(:mod:`ringtune.shaping.reading_notes` says it with the rest).

:data:`KLIPPER_COMMANDS`: every command Klipper registers (``register_command``,
``register_mux_command``) or handles (a ``cmd_NAME`` method) in klippy and klippy/extras of Klipper
84104bb (``shared/tools/klipper``), whichever modules a printer.cfg loads.
"""

from __future__ import annotations


KLIPPER_COMMANDS = frozenset("""
    ABORT ACCELEROMETER_DEBUG_READ ACCELEROMETER_DEBUG_WRITE ACCELEROMETER_MEASURE
    ACCELEROMETER_QUERY ACCEPT ACTIVATE_EXTRUDER ADJUSTED ANGLE_CALIBRATE ANGLE_CHIP_CALIBRATE
    ANGLE_DEBUG_READ ANGLE_DEBUG_WRITE AXIS_TWIST_COMPENSATION_CALIBRATE BED_MESH_CALIBRATE
    BED_MESH_CLEAR BED_MESH_MAP BED_MESH_OFFSET BED_MESH_OUTPUT BED_MESH_PROFILE BED_SCREWS_ADJUST
    BED_TILT_CALIBRATE BLTOUCH_DEBUG BLTOUCH_STORE CALC_MEASURED_SKEW CALIBRATE CANCEL_PRINT
    CLEAR_PAUSE DELTA_ANALYZE DELTA_CALIBRATE DISABLE_FILAMENT_WIDTH_LOG
    DISABLE_FILAMENT_WIDTH_SENSOR DUMP_TMC ECHO EDDY_CALIBRATE ENABLE_FILAMENT_WIDTH_LOG
    ENABLE_FILAMENT_WIDTH_SENSOR ENDSTOP_PHASE_CALIBRATE EXCLUDE_OBJECT EXCLUDE_OBJECT_DEFINE
    EXCLUDE_OBJECT_END EXCLUDE_OBJECT_START FIRMWARE_RESTART FORCE_MOVE G0 G1 G10 G11 G17 G18 G19 G2
    G20 G21 G28 G3 G4 G90 G91 G92 GET_CURRENT_SKEW GET_POSITION GET_RETRACTION HELP INIT_TMC
    LDC_CALIBRATE LDC_CALIBRATE_DRIVE_CURRENT LOAD_CELL_CALIBRATE LOAD_CELL_DIAGNOSTIC
    LOAD_CELL_READ LOAD_CELL_TARE LOAD_CELL_TEST_TAP M104 M105 M106 M107 M109 M110 M112 M114 M115
    M117 M118 M119 M140 M18 M190 M20 M204 M21 M220 M221 M23 M24 M25 M26 M27 M400 M405 M406 M407 M73
    M82 M83 M84 MANUAL_PROBE MANUAL_STEPPER MEASURE_AXES_NOISE NEXT O1 O21 O22 O23 O24 O25 O26 O27
    O28 O29 O30 O31 O32 O9 PALETTE_CLEAR PALETTE_CONNECT PALETTE_CUT PALETTE_DISCONNECT
    PALETTE_SMART_LOAD PAUSE PID_CALIBRATE PROBE PROBE_ACCURACY PROBE_CALIBRATE
    PROBE_EDDY_CURRENT_CALIBRATE PROBE_EDDY_CURRENT_TAP_CALIBRATE QUAD_GANTRY_LEVEL QUERY_ADC
    QUERY_BUTTON QUERY_ENDSTOPS QUERY_FILAMENT_SENSOR QUERY_FILAMENT_WIDTH QUERY_PROBE
    QUERY_RAW_FILAMENT_WIDTH RESET_FILAMENT_WIDTH_SENSOR RESET_SMART_EFFECTOR RESPOND RESTART
    RESTORE_DUAL_CARRIAGE_STATE RESTORE_GCODE_STATE RESUME SAVE_CONFIG SAVE_DUAL_CARRIAGE_STATE
    SAVE_GCODE_STATE SAVE_VARIABLE SCREWS_TILT_CALCULATE SDCARD_LOOP_BEGIN SDCARD_LOOP_DESIST
    SDCARD_LOOP_END SDCARD_PRINT_FILE SDCARD_RESET_FILE SET_DIGIPOT SET_DISPLAY_GROUP
    SET_DISPLAY_TEXT SET_DUAL_CARRIAGE SET_EXTRUDER_ROTATION_DISTANCE SET_E_ROTATION_DISTANCE
    SET_FAN_SPEED SET_FILAMENT_SENSOR SET_GCODE_OFFSET SET_GCODE_VARIABLE SET_HEATER_TEMPERATURE
    SET_IDLE_TIMEOUT SET_INPUT_SHAPER SET_KINEMATIC_POSITION SET_LED SET_LED_TEMPLATE SET_PIN
    SET_PRESSURE_ADVANCE SET_PRINT_STATS_INFO SET_RETRACTION SET_SERVO SET_SKEW SET_SMART_EFFECTOR
    SET_STEPPER_CARRIAGES SET_STEPPER_ENABLE SET_TEMPERATURE_FAN_TARGET SET_TMC_CURRENT
    SET_TMC_FIELD SET_VELOCITY_LIMIT SET_Z_THERMAL_ADJUST SHAPER_CALIBRATE SKEW_PROFILE STATUS
    STEPPER_BUZZ SYNC_EXTRUDER_MOTION TAP_CALIBRATE TARE TEMPERATURE_PROBE_ABORT
    TEMPERATURE_PROBE_CALIBRATE TEMPERATURE_PROBE_COMPLETE TEMPERATURE_PROBE_ENABLE
    TEMPERATURE_PROBE_NEXT TEMPERATURE_WAIT TESTZ TEST_RESONANCES TUNING_TOWER TURN_OFF_HEATERS
    UPDATE_DELAYED_GCODE Z_ENDSTOP_CALIBRATE Z_OFFSET_APPLY_DELTA_ENDSTOPS Z_OFFSET_APPLY_ENDSTOP
    Z_OFFSET_APPLY_PROBE Z_TILT_ADJUST
""".split())


def macro_calls(job) -> dict[str, list[int]]:
    """{command: the job's line numbers, in order} of the commands of a parsed job
    (:class:`ringtune.shaping.job.Job`) that are not Klipper's own (:data:`KLIPPER_COMMANDS`), but
    the limit and shaper commands of other firmwares (M201, M205, M593 …: said apart, by
    :mod:`ringtune.shaping.klipper_ignores` and :func:`ringtune.shaping.job_shapers.foreign_shapers`)."""
    out: dict[str, list[int]] = {}
    for ev in job.events:
        if ev.kind not in ("limits", "shaper") and ev.command.upper() not in KLIPPER_COMMANDS:
            out.setdefault(ev.command.upper(), []).append(int(ev.line))
    return out


def macro_note(calls: dict[str, list[int]]) -> str | None:
    """One sentence on ``calls`` (:func:`macro_calls`; None: there are none)."""
    if not calls:
        return None
    shown = list(calls.items())[:6]
    parts = ", ".join(f"{name} ×{len(lines)} (line {lines[0]})" for name, lines in shown)
    more = f" and {len(calls) - len(shown)} more" if len(calls) > len(shown) else ""
    return (f"the job calls commands that are not Klipper's own — {parts}{more}: macros of your printer.cfg "
            "where it defines them (else Klipper answers \"Unknown command\" and goes on), whose commands are not "
            "in the file; ringtune reads the job as if they set neither the acceleration nor the input shaper (a "
            "macro that does — a start macro's SET_VELOCITY_LIMIT, a per-feature acceleration macro — makes the "
            "printer run the job otherwise: put those settings in the job itself)")

