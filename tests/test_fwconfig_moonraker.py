"""Against real Klipper + Moonraker (fixture ``real_klipper``): ``from-klipper --moonraker`` gives the
same printer as ``from-klipper`` on the printer.cfg Klipper was started with — Klipper's own parse
(``configfile.settings``) is the independent truth for the file reader."""

from __future__ import annotations

import json

import pytest

from ringtune.agents.cli import main as cli
from ringtune.hardware.klipper_config import printer_facts_from_klipper, printer_facts_from_moonraker


def _without_source(description: dict) -> dict:
    d = json.loads(json.dumps(description))
    d["current"].pop("source")            # the file's path against Moonraker's URL
    return d


def _defaults(notes: list[str]) -> set[str]:
    return {n for n in notes if "Klipper's default" in n}


@pytest.mark.slow
def test_moonraker_gives_the_printer_of_the_file_klipper_read(real_klipper, capsys):
    from_file = printer_facts_from_klipper(real_klipper.printer_cfg)
    from_mr = printer_facts_from_moonraker(real_klipper.moonraker_url)
    assert _without_source(from_mr.description) == _without_source(from_file.description)
    # klipperd's printer.cfg: cartesian, max_accel 3000, rotation_distance 40, mzv 50 / 40 Hz
    d = from_file.description
    assert d["kinematics"] == "cartesian" and d["limits"]["accel"] == 3000.0
    assert d["motor"]["rotation_distance"] == 40.0
    assert (d["current"]["shaper_x"], d["current"]["freq_x"]) == ("mzv", 50.0)
    # what Klipper filled in (not in the file) is said aloud by both, the same way
    assert _defaults(from_mr.notes) == _defaults(from_file.notes)
    assert "[printer] square_corner_velocity not set: Klipper's default 5 mm/s is used" in from_file.notes
    # and through the command, --json
    assert cli.main(["printer", "from-klipper", "--moonraker", real_klipper.moonraker_url, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["firmware"] == "klipper" and _without_source(out["description"]) == _without_source(d)


SAVED = """\
[input_shaper]
shaper_type_x: ei   ; the X shaper
shaper_freq_x: 61.5 # measured
shaper_freq_y: 40
damping_ratio_y: 0.07

#*# <---------------------- SAVE_CONFIG ---------------------->
#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.
#*#
#*# [input_shaper]
#*# shaper_freq_y = 35.0
#*# shaper_type_y = zv
#*#
"""


@pytest.mark.slow
def test_comments_and_save_config_block_read_as_klipper_reads_them(real_klipper):
    """A SAVE_CONFIG block that fills in shaper_type_y and conflicts on shaper_freq_y: the file
    reader and Klipper agree on both (type zv from the block, frequency 40 from above it)."""
    try:
        real_klipper.restart(SAVED)
        from_file = printer_facts_from_klipper(real_klipper.printer_cfg)
        from_mr = printer_facts_from_moonraker(real_klipper.moonraker_url)
    finally:
        real_klipper.restart()
    assert _without_source(from_mr.description) == _without_source(from_file.description)
    cur = from_file.description["current"]
    assert (cur["shaper_x"], cur["freq_x"], cur["damping_x"]) == ("ei", 61.5, 0.1)
    assert (cur["shaper_y"], cur["freq_y"], cur["damping_y"]) == ("zv", 40.0, 0.07)


def test_an_unreachable_moonraker_is_one_line(capsys):
    rc = cli.main(["printer", "from-klipper", "--moonraker", "http://127.0.0.1:9"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("ringtune printer: error:")
    assert "Moonraker" in err[0]


@pytest.mark.parametrize("argv", [["printer", "from-klipper"],
                                  ["printer", "from-klipper", "x.cfg", "--moonraker", "http://h:7125"]])
def test_file_or_moonraker_exactly_one(argv, capsys):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "give printer.cfg or --moonraker URL" in err[0]
