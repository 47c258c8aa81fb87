"""Figures that commands write: one style, one writer, and a record of what each figure says.

Every report (the fit's, the camera calibration's, the crosstalk measurement's, the avatar
diagnostics') draws its figures with :func:`write_figures`: a figure of a given size in pixels
at :data:`DPI`, fonts of at least 10 pt (:data:`STYLE`), written atomically as PNG with a text
chunk (:data:`RECORD_KEY`) recording its title, axes labels, texts and the numbers it states
(:func:`figure_record`), read back by :func:`read_figure_record` so tests can check a figure
against the summary it illustrates.  matplotlib (Agg) is imported only when a figure is drawn.
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np

from .files.atomic import write_bytes_atomic

DPI = 100
STYLE = {"font.size": 12, "axes.titlesize": 13, "axes.labelsize": 12, "xtick.labelsize": 11,
         "ytick.labelsize": 11, "legend.fontsize": 11}


def jsonable(value):
    """``value`` as JSON can hold it (numpy scalars and arrays); TypeError otherwise."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def write_figures(directory: Path, drawings, sizes: dict, subject) -> dict[str, dict]:
    """Draw each ``(name, draw)`` of ``drawings`` as ``draw(fig, subject)`` on a figure of ``sizes[name]``
    pixels (the report style: fonts of at least 10 pt) and write it as ``directory/name``, atomically.

    ``draw`` may return a dict of the numbers its titles and labels state.  Each PNG records its
    texts and those numbers (:func:`figure_record`) in a text chunk, read back by
    :func:`read_figure_record`, so what a figure says can be checked against the summary it
    illustrates.  Returns {name: record}.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    records = {}
    with plt.rc_context(STYLE):
        for name, draw in drawings:
            w, h = sizes[name]
            fig = plt.figure(figsize=(w / DPI, h / DPI), dpi=DPI)
            try:
                record = figure_record(fig, draw(fig, subject) or {})
                buf = io.BytesIO()
                fig.savefig(buf, format="png", dpi=DPI,
                            metadata={RECORD_KEY: json.dumps(record, default=jsonable, ensure_ascii=True)})
            finally:
                plt.close(fig)
            write_bytes_atomic(directory / name, buf.getvalue())
            records[name] = record
    return records


RECORD_KEY = "lenticalib-figure"  # the PNG text chunk holding a figure's record


def figure_record(fig, numbers: dict) -> dict:
    """What a drawn figure says: ``title`` (the figure's title), ``axes`` (per axes, colour bars
    included: ``title``, ``xlabel``, ``ylabel``, ``texts`` written on it, ``legend``), and
    ``numbers`` (the values its texts state, as the drawing returned them)."""
    axes = []
    for ax in fig.axes:
        legend = ax.get_legend()
        axes.append({"title": " ".join(t for t in (ax.get_title("left"), ax.get_title(), ax.get_title("right")) if t),
                     "xlabel": ax.get_xlabel(), "ylabel": ax.get_ylabel(),
                     "texts": [t.get_text() for t in ax.texts],
                     "legend": [t.get_text() for t in legend.get_texts()] if legend else []})
    suptitle = fig._suptitle.get_text() if getattr(fig, "_suptitle", None) is not None else ""
    return {"title": suptitle or (axes[0]["title"] if axes else ""), "axes": axes, "numbers": numbers}


def read_figure_record(path: str | os.PathLike) -> dict:
    """The record :func:`write_figures` wrote into the PNG at ``path`` (see :func:`figure_record`)."""
    from PIL import Image

    with Image.open(path) as image:
        return json.loads(image.text[RECORD_KEY])


