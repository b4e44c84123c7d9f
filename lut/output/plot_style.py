"""What every lutgen figure shares: a pyplot-free matplotlib figure, phase markers, PNG saving with a title.

Figures are made with :class:`matplotlib.figure.Figure` directly, not ``pyplot``: no global figure
registry (nothing leaks when a caller makes hundreds), and the Agg canvas is used whatever backend the
caller's matplotlib is set to.
"""

from __future__ import annotations

from pathlib import Path

from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

DPI = 110
LIMIT_STYLE = {"color": "tab:red", "linestyle": "--", "linewidth": 1.2}
PHASE_LINE_STYLE = {"color": "0.35", "linestyle": ":", "linewidth": 1.0}


def new_figure(width_in: float, height_in: float) -> Figure:
    """A figure (size in inches) on the Agg canvas, with constrained layout (titles and labels never overlap)."""
    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def mark_phases(ax: Axes, phases: dict[str, tuple[float, float]], label: bool = True) -> None:
    """Dotted vertical lines at the phase boundaries inside the axes' time range; phase names above the frame.

    Call after the data are plotted (the x range must be final). ``phases``: name -> (t_start, t_end) in s.
    """
    lo, hi = ax.get_xlim()
    boundaries = sorted({t for span in phases.values() for t in span})
    for t in boundaries:
        if lo <= t <= hi:
            ax.axvline(t, **PHASE_LINE_STYLE, zorder=0)
    ax.set_xlim(lo, hi)  # axvline must not widen the view
    if not label:
        return
    for name, (t0, t1) in phases.items():
        a, b = max(t0, lo), min(t1, hi)
        if b - a > 0.06 * (hi - lo):  # only where the name fits
            # just above the frame: never on the data or the legend
            ax.text((a + b) / 2, 1.0, name, transform=ax.get_xaxis_transform(), ha="center", va="bottom",
                    fontsize=8, color="0.3")


def save_figure(fig: Figure, path: Path, title: str) -> Path:
    """Set the figure title, write a PNG whose ``Title`` metadata is that title, and return the path."""
    fig.suptitle(title, fontsize=12)
    path = Path(path)
    fig.savefig(path, dpi=DPI, metadata={"Title": title, "Software": "lutgen"})
    return path
