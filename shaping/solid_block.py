"""A tall solid block as G-code: the heavy job that moves a bed slinger's Y mode (mm, mm/s).

Each layer: a Z change, the outer wall (``;TYPE:External perimeter``, 60 mm/s) and rectilinear
solid infill (``;TYPE:Solid infill``, 100 mm/s, alternating X and Y), with a retraction and a z-hop
travel that deposit nothing. Relative E; a line is ``width × layer`` mm² of plastic. The default
60 × 60 × 90 mm block of PLA is about 400 g — a third of an Ender-3 bed.
"""

from __future__ import annotations

import math

import numpy as np

from ringtune.shaping.layers import FILAMENT_DIAMETER_MM


def solid_block(size_mm: float = 60.0, height_mm: float = 90.0, layer_mm: float = 0.3, width_mm: float = 0.45,
                filament_mm: float = FILAMENT_DIAMETER_MM) -> tuple[str, np.ndarray]:
    """(G-code, mm of filament each layer extrudes) of a ``size_mm`` square block ``height_mm`` tall."""
    per_mm = width_mm * layer_mm / (math.pi * filament_mm ** 2 / 4)
    out, e_layers = ["G90", "M83", "G28", "G92 E0"], []
    x0 = y0 = 50.0
    inner = size_mm - 2 * width_mm
    for k in range(int(round(height_mm / layer_mm))):
        z = (k + 1) * layer_mm
        e = 0.0
        out += [";LAYER_CHANGE", f"G1 Z{z:.2f} F600", f"G0 X{x0:.3f} Y{y0:.3f} F6000", "G1 E0.8 F2400",
                ";TYPE:External perimeter"]
        for x, y in ((x0 + size_mm, y0), (x0 + size_mm, y0 + size_mm), (x0, y0 + size_mm), (x0, y0)):
            out.append(f"G1 X{x:.3f} Y{y:.3f} E{size_mm * per_mm:.5f} F3600")
            e += round(size_mm * per_mm, 5)
        out += ["G1 E-0.8 F2400", f"G0 Z{z + 0.4:.2f}", f"G0 X{x0 + width_mm:.3f} Y{y0 + width_mm:.3f}",
                f"G0 Z{z:.2f}", "G1 E0.8", ";TYPE:Solid infill"]
        for i in range(1, int(size_mm / width_mm) - 1):
            c = i * width_mm
            a, b = ((x0 + width_mm, y0 + c), (x0 + width_mm + inner, y0 + c)) if k % 2 == 0 else \
                ((x0 + c, y0 + width_mm), (x0 + c, y0 + width_mm + inner))
            if i % 2:
                a, b = b, a
            out.append(f"G1 X{a[0]:.3f} Y{a[1]:.3f} F6000")
            out.append(f"G1 X{b[0]:.3f} Y{b[1]:.3f} E{inner * per_mm:.5f}")
            e += round(inner * per_mm, 5)
        out.append("G1 E-0.8 F2400")
        e_layers.append(e)
    return "\n".join(out) + "\n", np.array(e_layers)
