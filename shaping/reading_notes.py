"""What a firmware does otherwise than a job reads, and what the job leaves unjudged, in one place,
each said once: ``tune`` and ``simulate`` print these notes beside their figures, which are judged
as the job reads."""

from __future__ import annotations

from ringtune.shaping.arcs import arcs_note
from ringtune.shaping.extruder_alone import extruder_alone_note
from ringtune.shaping.klipper_refusals import klipper_refusals, klipper_refusals_note
from ringtune.shaping.features import nothing_seen_note, purge_note
from ringtune.shaping.firmware_retraction import firmware_retraction_note
from ringtune.shaping.flavor_units import flavor_note
from ringtune.shaping.job_shapers import foreign_shapers, foreign_shapers_note, prusa_weight_note
from ringtune.shaping.klipper_commands import macro_calls, macro_note
from ringtune.shaping.klipper_ignores import klipper_ignored, klipper_ignored_note


def reading_notes(job, limits, firmware: str | None) -> list[str]:
    """What ``firmware`` does otherwise than the job reads, each said once:

    - where ``limits`` (the :class:`ringtune.shaping.planner.MachineLimits` it is planned with) read
      it as Klipper does, the limit lines Klipper does not act on
      (:mod:`ringtune.shaping.klipper_ignores`) and the commands that are not Klipper's own
      (:func:`ringtune.shaping.klipper_commands.macro_note`);
    - the shaper commands ``firmware`` does not have
      (:func:`ringtune.shaping.job_shapers.foreign_shapers`) and, on Prusa's, the printed weight the
      job gives it (:func:`ringtune.shaping.job_shapers.prusa_weight_note`); ``firmware`` None:
      neither is said;
    - the firmware retractions (:mod:`ringtune.shaping.firmware_retraction`);
    - how its arcs are cut (:func:`ringtune.shaping.arcs.arcs_note`);
    - on Klipper, retractions planned without the extruder's own limits
      (:func:`ringtune.shaping.extruder_alone.extruder_alone_note`), and the moves its extruder refuses
      (:func:`ringtune.shaping.klipper_refusals.klipper_refusals_note`);
    - a job that extrudes nothing a person sees (:func:`ringtune.shaping.features.nothing_seen_note`),
      or labels what is seen and extrudes more (:func:`ringtune.shaping.features.purge_note`);
    - the limit lines of a job sliced for another firmware that this one reads in other units, or
      not at all (:func:`ringtune.shaping.flavor_units.flavor_note`)."""
    notes = [klipper_ignored_note(klipper_ignored(job, limits)),
             macro_note(macro_calls(job)) if limits.reads_like_klipper else None,
             foreign_shapers_note(foreign_shapers(job, firmware), firmware) if firmware else None,
             prusa_weight_note(job, firmware) if firmware else None,
             firmware_retraction_note(job, limits), arcs_note(job, limits), extruder_alone_note(job, limits),
             klipper_refusals_note(klipper_refusals(job, limits)), nothing_seen_note(job), purge_note(job),
             flavor_note(job, limits, firmware)]
    return [n for n in notes if n]
