"""What the ``ringtune`` commands share: reading a config, checking an output path, the
firmware option, progress timing.

Each command is one module ``ringtune.agents.cli.NAME`` defining ``NAME``, optionally
``DESCRIPTION`` (shown by ``ringtune NAME --help``), ``add_arguments(parser)`` and
``run(args, out) -> int``; its one-line help is in :data:`ringtune.agents.cli.main.COMMANDS`.
Only the command being run is imported, so modules import what they use at their tops.
"""

import argparse
import os
from pathlib import Path

from ringtune.envs.printer_model import unmeasured_note
from ringtune.envs.variants import TWIN_DAMPING
from ringtune.shaping.builtin_jobs import BUILTIN_JOBS, job_path
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.errors import RingtuneError
from ringtune.shaping.firmware import Firmware
from ringtune.shaping.gcode_file import refuse_binary_output

#: seconds between progress lines when stderr is not a terminal (``RINGTUNE_PROGRESS_S`` overrides)
PROGRESS_INTERVAL_S = 10.0


def progress_interval() -> float:
    """Seconds between progress lines on a non-terminal stderr: ``RINGTUNE_PROGRESS_S``, else
    :data:`PROGRESS_INTERVAL_S`."""
    return float(os.environ.get("RINGTUNE_PROGRESS_S", PROGRESS_INTERVAL_S))


def firmware_name(text: str) -> str:
    """argparse type of every ``--firmware``: the firmware record's name in any case (``Klipper``,
    ``RRF``); a refusal naming the firmwares there are."""
    try:
        return Firmware.named(text).name
    except RingtuneError as exc:
        raise argparse.ArgumentTypeError(exc.bare) from None


#: what --gcode's help adds: the built-in jobs by name
GCODE_JOB_HELP = (f"plain or Prusa binary (.bgcode), or a built-in job: {', '.join(BUILTIN_JOBS)} (a sliced test part, "
                  "about 20 min)")


def gcode_job(text: str) -> str:
    """argparse type of a G-code job option: a built-in job's name (``part``) becomes its file."""
    return job_path(text)


def load_config(path, out=None):
    """``TuneConfig.load(path)``, with a note on stderr (through ``out``) for each key that looks
    misspelt; None without a path (an optional --config not given)."""
    if not path:
        return None
    cfg = TuneConfig.load(path)
    if out is not None:
        out.note(*cfg.likely_typos(), kind=f"{path}: warning")
    return cfg


def check_output_folder(option: str, path) -> None:
    """Refuse, before any work, an output file whose folder does not exist, or that is itself a
    folder (one-line error)."""
    if not path:
        return
    if not Path(path).parent.is_dir():
        raise RingtuneError(f"no such directory {str(Path(path).parent)!r} (a file's folder must exist: make it "
                            "first; only folder outputs such as tune --out are created)", f"{option} {path}")
    if Path(path).is_dir():
        raise RingtuneError("is a directory; give a file name", f"{option} {path}")


def check_gcode_output(option: str, path) -> None:
    """:func:`check_output_folder` for a G-code output, which must not be named ``.bgcode``."""
    check_output_folder(option, path)
    refuse_binary_output(option, path)


def judgement(freq_margin: float) -> str:
    """How a command's quality figures were judged, in words (``freq_margin`` a fraction):
    the exact model, or the worst of it and its resonances ± the margin (as ``tune`` judges)."""
    if not freq_margin:
        return "on the exact model (--freq-margin 0)"
    return (f"worst of the model and its resonances ±{freq_margin * 100:g} % with damping ×{TWIN_DAMPING:g} "
            f"(--freq-margin {freq_margin * 100:g})")


def say_unmeasured(printer, out) -> None:
    """Say aloud that a description's modes were not measured (:func:`unmeasured_note`)."""
    message = unmeasured_note(printer)
    if message:
        out.note(message)
