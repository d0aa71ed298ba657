"""Progress bars over a computation's blocks (:func:`over_blocks`). tqdm is imported when a bar
is shown: it imports importlib.metadata, 20-30 ms of every command's start otherwise. The monitor
thread tqdm starts with a bar is stopped when the last bar has ended: left running, it would keep
:func:`rcm_kin.apart.run_apart` from forking (it forks only while no other thread runs)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence


def over_blocks(starts: Sequence, show: bool, desc: str, unit: str) -> Iterator:
    """``starts`` one by one, with a bar ``desc`` counting ``unit`` when ``show`` and there is more
    than one."""
    if not show or len(starts) < 2:
        yield from starts
        return
    from tqdm import tqdm

    try:
        with tqdm(starts, desc=desc, unit=unit) as bar:
            yield from bar
    finally:
        monitor = tqdm.monitor
        if monitor is not None and not monitor.get_instances():
            monitor.exit()
