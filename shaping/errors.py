"""The one error type every ringtune package raises for bad input.

The CLI turns it into a single line on stderr and a non-zero exit, never a traceback, so the
message must name *what* is wrong and *where* (file and line, TOML key, CLI option).
"""

from __future__ import annotations


class RingtuneError(ValueError):
    """Bad input or an impossible request, with a message fit to show a user as it is.

    ``where`` (optional) is prefixed to the message: ``"job.gcode:12"``, ``"printer.toml: [x].modes"``,
    ``"--freq"``.
    """

    def __init__(self, message: str, where: str | None = None):
        self.where = where
        self.bare = message
        super().__init__(f"{where}: {message}" if where else message)

    def relocated(self, prefix: str, new: str) -> "RingtuneError":
        """The same error with a location starting ``prefix`` (e.g. the abstract ``"config"``)
        moved to ``new`` (the file the user gave); no location becomes ``new``."""
        where = self.where or prefix
        if where.split(":")[0] != prefix:
            return self
        return RingtuneError(self.bare, new + where[len(prefix):])
