"""One module per ``ringtune`` subcommand.

Each module defines ``NAME``, ``HELP`` (one line), optionally ``DESCRIPTION`` (shown by
``ringtune NAME --help``), ``add_arguments(parser)`` and ``run(args, out) -> int``. Heavy imports
(mujoco, optuna, torch) happen inside ``run`` so that ``ringtune --help`` stays instant.
"""


def load_config(path, out=None):
    """``TuneConfig.load(path)``, with a note on stderr (through ``out``) for each key that looks
    misspelt."""
    from ringtune.shaping.config import TuneConfig

    cfg = TuneConfig.load(path)
    for message in cfg.likely_typos() if out is not None else ():
        out.note(f"{path}: warning: {message}")
    return cfg


def check_output_folder(option: str, path) -> None:
    """Refuse, before any work, an output file whose folder does not exist, or that is itself a
    folder (one-line error)."""
    from pathlib import Path

    from ringtune.shaping.errors import RingtuneError

    if path and not Path(path).parent.is_dir():
        raise RingtuneError("no such directory", f"{option} {path}")
    if path and Path(path).is_dir():
        raise RingtuneError("is a directory; give a file name", f"{option} {path}")


def judgement(freq_margin: float) -> str:
    """How a command's quality figures were judged, in words (``freq_margin`` a fraction):
    the exact model, or the worst of it and its resonances ± the margin (as ``tune`` judges)."""
    if not freq_margin:
        return "on the exact model (--freq-margin 0)"
    return (f"worst of the model and its resonances ±{freq_margin * 100:g} % "
            f"(--freq-margin {freq_margin * 100:g})")
