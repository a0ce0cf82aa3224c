"""One module per ``ringtune`` subcommand.

Each module defines ``NAME``, ``HELP`` (one line), optionally ``DESCRIPTION`` (shown by
``ringtune NAME --help``), ``add_arguments(parser)`` and ``run(args, out) -> int``. Heavy imports
(mujoco, optuna, torch) happen inside ``run`` so that ``ringtune --help`` stays instant.
"""


def load_config(path, out):
    """``TuneConfig.load(path)``, with a note on stderr for each key that looks misspelt."""
    from ringtune.shaping.config import TuneConfig

    cfg = TuneConfig.load(path)
    for message in cfg.likely_typos():
        out.note(f"{path}: warning: {message}")
    return cfg
