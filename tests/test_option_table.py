"""The option table (agents/cli/options.py) on the commands that branched on their own values
before: shaper, response, push and graph refuse an out-of-range value at parse time, in one line naming
the option and the table's range, exit status 2, nothing on stdout."""

from __future__ import annotations

import pytest

from ringtune.agents.cli.main import main
from ringtune.agents.cli.options import VALUES, ListOf


@pytest.mark.parametrize("argv,needle", [
    (["shaper", "zv", "--freq", "0"], "--freq: must be a frequency > 0 Hz"),
    (["shaper", "zv", "--freq", "40", "--damping", "1"], "--damping: must be a damping ratio in [0, 1)"),
    (["shaper", "zv", "--freq", "40", "--accel", "0"], "--accel: must be an acceleration > 0 mm/s²"),
    (["shaper", "zv", "--freq", "40", "--scv", "-1"], "--scv: must be a square-corner velocity ≥ 0 mm/s"),
    (["response", "zv", "--freq", "40", "--fmax", "-3"], "--fmax: must be a frequency > 0 Hz"),
    (["response", "zv", "--freq", "40", "--points", "9"], "--points: must be a number of points 10 to 100000"),
    (["response", "zv", "--freq", "40", "--plant-damping", "0.1,1"], "--plant-damping: must be a damping ratio"),
    (["response", "zv", "--freq", "40", "--plant-damping", ","], "--plant-damping: expected values"),
    (["response", "zv", "--freq", "40", "--flavor", "duet"], "--flavor: unknown flavour 'duet'"),
    (["push", "c.json", "--dry-run", "--timeout", "0"], "--timeout: must be a time > 0 s"),
    (["push", "c.json", "--dry-run", "--baud", "-9600"], "--baud: must be a serial speed > 0 baud"),
    (["push", "c.json", "--port", "/tmp/p", "--moonraker", "http://h"], "--moonraker: not allowed with"),
    (["graph", "shapers", "x.csv", "-o", "g.png", "--scv", "-1"], "--scv: must be a square-corner velocity ≥ 0"),
    (["graph", "speeds", "-o", "g.png", "--step", "0"], "--step: must be a speed > 0 mm/s"),
])
def test_out_of_range_is_refused_before_the_command_runs(capsys, argv, needle):
    assert main(argv) == 2
    cap = capsys.readouterr()
    assert cap.out == "" and needle in cap.err and len(cap.err.strip().splitlines()) == 1


def test_range_ends_as_the_table_says():
    """A closed end is taken, an open end refused: the edges of the table's own ranges."""
    assert VALUES["points"]("10") == 10 and VALUES["points"]("100000") == 100_000
    assert VALUES["damping_ratio"]("0") == 0.0
    assert VALUES["scv"]("0") == 0.0
    for value, text in (("damping_ratio", "1"), ("freq", "0"), ("seconds", "nan"), ("points", "10.5")):
        with pytest.raises(Exception, match="must be"):
            VALUES[value](text)
    assert ListOf(VALUES["damping_ratio"])(" 0.075, 0.1 ,0.15,") == [0.075, 0.1, 0.15]


def test_flavour_names_resolve_to_their_formulas(capsys):
    """A firmware name picks its formulas (prusa -> klipper-legacy), as `shaper --help` says."""
    assert main(["shaper", "mzv", "--freq", "40", "--flavor", "prusa", "--json"]) == 0
    assert '"flavor": "klipper-legacy"' in capsys.readouterr().out
