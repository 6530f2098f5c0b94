"""Checks of the publication style that look at what a figure really holds: the PDF's fonts and
page size, the PNG's pixel width, the font sizes of every drawn text, and whether each marker
drawn has a legend entry of the same marker, colour and fill."""
import re

import matplotlib
from matplotlib.colors import to_rgba
from matplotlib.lines import Line2D

NO_MARKER = (None, "", " ", "None", "none")


def pdf_font_kinds(pdf):
    """The /Subtype of every font dictionary in a PDF's bytes (matplotlib writes them uncompressed)."""
    return set(re.findall(rb"/Subtype\s*/(Type3|TrueType|CIDFontType2|Type1|Type0|CIDFontType0)", pdf))


def pdf_width_inches(pdf):
    """Width of the PDF's first page [in] from its /MediaBox."""
    box = re.search(rb"/MediaBox\s*\[\s*([-\d.]+)\s+([-\d.]+)\s+([-\d.]+)\s+([-\d.]+)\s*\]", pdf)
    return (float(box.group(3)) - float(box.group(1))) / 72.0


def drawn_font_sizes(fig):
    """Font size [pt] of every visible, non-empty text of a drawn figure (tick labels included)."""
    fig.canvas.draw()
    return [text.get_fontsize() for text in fig.findobj(matplotlib.text.Text)
            if text.get_visible() and text.get_text().strip()]


def _signature(line):
    return (line.get_marker(), to_rgba(line.get_color()), to_rgba(line.get_markerfacecolor()))


def unexplained_markers(fig):
    """Markers drawn on the axes that no legend entry shows (same marker, colour and fill)."""
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    explained = {_signature(handle) for legend in legends for handle in legend.legend_handles
                 if isinstance(handle, Line2D) and handle.get_marker() not in NO_MARKER}
    return [line for ax in fig.axes for line in ax.get_lines()
            if line.get_visible() and line.get_marker() not in NO_MARKER and len(line.get_xdata())
            and _signature(line) not in explained]


def marked_lines(fig):
    """Every visible line with a marker, on every axes."""
    return [line for ax in fig.axes for line in ax.get_lines()
            if line.get_visible() and line.get_marker() not in NO_MARKER and len(line.get_xdata())]
