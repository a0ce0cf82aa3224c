"""The printer variants a configuration is judged on: the model as fitted and, with a frequency
margin, its twins with every resonance moved and every damping ratio lowered (``tune`` takes the
worst of them: :func:`ringtune.envs.evaluate.evaluate_judged`)."""

from __future__ import annotations

from typing import NamedTuple

#: damping ratio factor of the detuned twins a configuration is judged on (:func:`variant_factors`):
#: a damping ratio fitted to a resonance test is less certain than its frequency, and a longer ring
#: after each corner is the side that hurts;
#: Klipper's calibrate_shaper likewise takes the worst remaining vibration over test dampings
#: 0.075–0.15 around its 0.1 (its low end, 0.75×)
TWIN_DAMPING = 0.75

#: fraction: by default every configuration is judged on the printer and on the printer with all
#: resonances 5 % lower and 5 % higher (damping ratios × TWIN_DAMPING), and the worst quality
#: counts (``evaluate_many``'s ``freq_margin``): a real printer's frequencies drift by that much
#: (print mass on the bed, toolhead position, a resonance test's 1.5 Hz bins), its damping is less
#: certain still, and a shaper at the edge of its band on the exact model does not survive it
DEFAULT_FREQ_MARGIN = 0.05


class Variant(NamedTuple):
    """A printer variant a configuration is judged on: every mode's frequency × ``freq`` and damping
    ratio × ``damping`` (:meth:`ringtune.envs.printer_model.Printer.detuned`)."""

    freq: float
    damping: float = 1.0

    @property
    def exact(self) -> bool:
        """Whether this is the printer as modelled."""
        return self.freq == 1.0 and self.damping == 1.0

    def of(self, printer):
        """``printer`` as this variant."""
        return printer if self.exact else printer.detuned(self.freq, self.damping)

    def words(self) -> str:
        """The variant in words (plot titles, notes)."""
        if self.exact:
            return "the printer as modelled"
        if self.freq == 1.0:
            return f"the printer with its resonances as modelled and damping ×{self.damping:g}"
        way = "lower" if self.freq < 1 else "higher"
        return (f"the printer with its resonances {abs(self.freq - 1) * 100:g} % {way}"
                + (f" and damping ×{self.damping:g}" if self.damping != 1.0 else ""))


def variant_factors(freq_margin: float) -> tuple[Variant, ...]:
    """The printer variants a configuration is judged on: the exact model alone without a margin;
    with one (a fraction), also its twins with every mode's frequency × (1 ∓ margin) and damping
    ratio × :data:`TWIN_DAMPING`."""
    if not freq_margin:
        return (Variant(1.0),)
    return (Variant(1.0), Variant(1.0 - freq_margin, TWIN_DAMPING), Variant(1.0 + freq_margin, TWIN_DAMPING))
