"""One module per ``ringtune`` subcommand.

Each module defines ``NAME``, ``HELP`` (one line), optionally ``DESCRIPTION`` (shown by
``ringtune NAME --help``), ``add_arguments(parser)`` and ``run(args, out) -> int``. Heavy imports
(mujoco, optuna, torch) happen inside ``run`` so that ``ringtune --help`` stays instant.
"""
