"""Writing a figure so that what it says can be read back: every text drawn on it (titles, labels,
legends, table cells) also goes into the PNG's ``Description`` text chunk, one per line, and its
title into ``Title``. Tests and tools compare those numbers with the command's ``--json`` without
reading pixels."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
from matplotlib.table import Table
from matplotlib.text import Text


def figure_texts(fig) -> list[str]:
    """Every visible non-empty text of ``fig``, in drawing-tree order; a table's cells row by row,
    tab-separated (one line per row)."""
    out = [t.get_text() for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]
    for table in fig.findobj(Table):
        rows: dict[int, list[str]] = {}
        for (r, c), cell in sorted(table.get_celld().items()):
            rows.setdefault(r, []).append(cell.get_text().get_text())
        out += ["\t".join(row) for row in rows.values()]
    return out


def save_figure(fig, path: str | Path, title: str = "", dpi: int = 110) -> Path:
    """Write ``fig`` to ``path`` (format from the suffix); PNGs carry :func:`figure_texts` in their
    ``Description`` chunk and ``title`` in ``Title``. The figure is closed."""
    out = Path(path)
    meta = None
    if out.suffix.lower() == ".png":
        meta = {"Title": title, "Description": "\n".join(figure_texts(fig))}
    fig.savefig(out, dpi=dpi, metadata=meta)
    plt.close(fig)
    return out
