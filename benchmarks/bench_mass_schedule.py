"""Schedules by printed mass (issue 22 item 3): what a fixed Y frequency costs on a tall print.

On the default printer (Ender-3 class bed slinger) with the 60 × 60 × 90 mm solid PLA block of
:mod:`ringtune.shaping.solid_block` (about 400 g), for a config aimed at the empty bed's dominant Y
mode (MZV) and for `tune`'s pick on this printer (README: Y 3hump_ei @ 77.1 Hz), prints the bands
and the last band simulated on the exact model with its mass on the bed: ripple (the worst visible
wall's peak-to-peak across it), corner rounding and the band's planned time at the fixed and at the
scheduled frequency, with and without the band accelerations, and the ratio fixed / scheduled
(acceptance: ripple at least halved).

    .venv/bin/python benchmarks/bench_mass_schedule.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from ringtune.agents.tune.mass_check import schedule_job
from ringtune.shaping.config import TuneConfig
from ringtune.shaping.solid_block import solid_block

CONFIGS = {
    "MZV at the empty bed's mode": TuneConfig(shaper_x="mzv", freq_x=45.5, shaper_y="mzv", freq_y=38.9, accel=3000),
    "tune's pick (3hump_ei 77.1 Hz)": TuneConfig(shaper_x="zvd", freq_x=57.6, damping_x=0.01, shaper_y="3hump_ei",
                                                 freq_y=77.1, damping_y=0.08, accel=4900),
}


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "block.gcode"
        path.write_text(solid_block()[0])
        for name, cfg in CONFIGS.items():
            for band_accel in ("keep", "auto"):
                t = time.perf_counter()
                s = schedule_job(cfg, None, path, band_accel=band_accel)
                wall = time.perf_counter() - t
                r = s.ripple
                fx, sc = r["fixed"], r["scheduled"]
                print(f"{name}, --band-accel {band_accel}: {s.total_kg * 1e3:.0f} g, {len(s.bands)} bands, "
                      f"Y mode {s.empty_mode_hz:.1f} -> {r['mode_hz']:.1f} Hz on the last band ({wall:.1f} s)")
                for label, v in (("fixed", fx), ("scheduled", sc)):
                    print(f"  {label:<9} {v['freq_y']:6.2f} Hz {v['accel']:6.0f} mm/s²  "
                          f"ripple {v['ripple_mm'] * 1e3:5.1f} µm  corner in {v['corner_in_mm'] * 1e3:5.1f} µm  time {v['print_time_s']:7.1f} s")
                print(f"  ripple fixed / scheduled = {fx['ripple_mm'] / sc['ripple_mm']:.2f} (target ≥ 2); "
                      f"corner in {sc['corner_in_mm'] / fx['corner_in_mm'] - 1:+.1%}; "
                      f"time {sc['print_time_s'] / fx['print_time_s'] - 1:+.1%}")


if __name__ == "__main__":
    main()
