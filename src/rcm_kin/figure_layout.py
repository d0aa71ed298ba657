"""Fixed margins that cost nothing to draw and still hold their labels: a figure's y tick labels
read from their text (not laid out) to widen its margins where they would not fit. Plain
matplotlib objects in, nothing imported: used by :func:`rcm_kin.plotting.save_figure`."""

from __future__ import annotations

# inches a tick label's characters take at 10 points (DejaVu Sans), a digit's for the others; and
# beside the labels, a y axis's tick, its pad and its axis label (measured: tests/plotting/test_figure_cost.py)
CHARACTER = {"\N{MINUS SIGN}": 0.116, "-": 0.116, ".": 0.044, "": 0.088}
BESIDE = 0.31
APART = 0.12          # inches between the labels of two axes facing each other


def shortfall(fig) -> tuple[float, float, float]:
    """How many inches the y tick labels of a figure on fixed margins lack (left margin, right
    margin, between two columns), read from their text without laying them out (a quarter of a
    drawing): each y axis needs :func:`y_axis_width` within the room to the figure's edge, or,
    with the labels facing it and :data:`APART`, to the next axes on that side. Zeros when
    everything fits."""
    width = fig.get_size_inches()[0]
    boxes = [(ax, _placed(ax)) for ax in fig.axes if ax.get_visible() and ax.name == "rectilinear"]
    need = {ax: y_axis_width(ax) for ax, _ in boxes}
    right = {ax: ax.yaxis.get_ticks_position() == "right" for ax, _ in boxes}
    lacking = [0.0, 0.0, 0.0]
    for ax, box in boxes:
        facing = [(b.x0 - box.x1 if right[ax] else box.x0 - b.x1, other) for other, b in boxes
                  if b.y0 < box.y1 and b.y1 > box.y0 and (b.x0 >= box.x1 if right[ax] else b.x1 <= box.x0)]
        gap = min((g for g, _ in facing), default=1 - box.x1 if right[ax] else box.x0)
        shared = max((need[o] + APART for g, o in facing if g <= gap + 1e-9 and right[o] != right[ax]), default=0.0)
        where = 2 if facing else int(right[ax])
        lacking[where] = max(lacking[where], need[ax] + shared - gap * width)
    return lacking[0], lacking[1], lacking[2]


def _placed(ax):
    """Where ``ax`` is drawn (figure fractions): a colour bar's locator and aspect applied as drawing does."""
    locator = ax.get_axes_locator()
    if locator is not None:
        ax.apply_aspect(locator(ax, None))
    return ax.get_position()


def widen(fig, left: float, right: float, between: float) -> None:
    """Move the figure's grid of axes ``left`` and ``right`` inches in from its edges and put
    ``between`` inches more between its columns (the axes narrower, nothing else moved)."""
    if max(left, right, between) <= 0.0:
        return
    grid = next(ax.get_subplotspec().get_topmost_subplotspec().get_gridspec() for ax in fig.axes
                if ax.get_subplotspec() is not None)
    width, params, n = fig.get_size_inches()[0], grid.get_subplot_params(fig), grid.ncols
    span = (params.right - params.left) * width
    spacing = params.wspace * span / (n + (n - 1) * params.wspace) + max(between, 0.0)
    left, right = params.left + max(left, 0.0) / width, params.right - max(right, 0.0) / width
    cell = ((right - left) * width - (n - 1) * spacing) / n
    if cell > 0.0:                   # else a figure too narrow for its labels: left as it is
        grid.update(left=left, right=right, wspace=spacing / cell)
        fig.subplots_adjust()        # the axes moved to their cells (the grid moves only pyplot's figures' axes)


def y_axis_width(ax) -> float:
    """Inches the y axis of ``ax`` takes beside it as drawn (tick labels, ticks, axis label), from the
    texts of its tick labels in view (:data:`CHARACTER`, :data:`BESIDE`), without laying them out."""
    return BESIDE + max((sum(CHARACTER.get(c, CHARACTER[""]) for c in label) for label in _tick_labels(ax.yaxis)),
                        default=0.0)


def _tick_labels(axis) -> list[str]:
    """The texts of ``axis``'s major tick labels within its limits, as drawn."""
    low, high = sorted(axis.get_view_interval())
    slack = 1e-9 * (high - low)
    locations = [x for x in axis.get_majorticklocs() if low - slack <= x <= high + slack]
    return axis.get_major_formatter().format_ticks(locations)
