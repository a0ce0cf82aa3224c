"""What to send, save and expect for one firmware: the :class:`Export` each dialect builds
(:mod:`ringtune.hardware.dialects`) and a push sends (:mod:`ringtune.hardware.push`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ringtune.shaping.firmware import FIRMWARES, Firmware


@dataclass
class Export:
    """What to send, save and expect for one firmware.

    Attributes:
        firmware: firmware name (a key of :data:`ringtune.shaping.firmware.FIRMWARES`).
        lines: G-code lines that apply the config now, in order.
        save_lines: lines that persist it on the printer (``M500``, ``M593 W``); empty if the
            firmware cannot save it from G-code.
        config_text: text for the firmware's config file (``printer.cfg`` section, ``config.g``
            lines), or None.
        config_target: where ``config_text`` belongs (e.g. ``"printer.cfg"``, ``"config.g"``).
        readback: commands whose reply reports the applied settings.
        expected: setting -> intended value, as :mod:`ringtune.hardware.readback` reports them:
            ``"x.type"``, ``"x.freq"``, ``"x.damping"`` (RRF: ``"all.*"``), ``"accel"``.
        setting_lines: setting -> index in ``lines`` of the line that sets it.
        notes: remarks for the user (e.g. no frequency limit in this firmware, and what to run).
    """

    firmware: str
    lines: list[str]
    save_lines: list[str] = field(default_factory=list)
    config_text: str | None = None
    config_target: str | None = None
    readback: list[str] = field(default_factory=list)
    expected: dict[str, object] = field(default_factory=dict)
    setting_lines: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def record(self) -> Firmware:
        return FIRMWARES[self.firmware]

    def render_commands(self) -> str:
        """The command part: the firmware's comment syntax and G-code lines only, so the whole text
        can be sent to the printer as a file (Klipper reads ``;`` comments, not ``#``)."""
        c = self.record.comment
        out = [f"{c} ringtune export for {self.record.title}"]
        out += [f"{c} note: {n}" for n in self.notes]
        out += self.lines
        if self.save_lines:
            out.append(f"{c} to keep it after a restart:")
            out += self.save_lines
        if self.config_text:
            out.append(f"{c} the {self.config_target} part is written separately (export --part config)")
        return "\n".join(out) + "\n"

    def render_config(self) -> str | None:
        """The config-file part (``printer.cfg`` section, ``config.g`` lines), or None."""
        if not self.config_text:
            return None
        c, replaces = (("#", " (it replaces an existing [input_shaper] section)")
                       if self.config_target == "printer.cfg" else (self.record.comment, ""))
        head = f"{c} ringtune export for {self.record.title}: put this in {self.config_target}{replaces}"
        return head + "\n" + self.config_text.rstrip("\n") + "\n"

    def render(self) -> str:
        """Both parts, the config part after a comment line saying where it belongs."""
        cfg = self.render_config()
        return self.render_commands() + ("" if cfg is None else "\n" + cfg)
