"""Progress bars over blocks (rcm_kin.progress.over_blocks): every block once, a bar only when
asked and worth it, and no tqdm thread left behind once the last bar ends."""

from __future__ import annotations

import threading

import pytest
from tqdm import tqdm

from rcm_kin.progress import over_blocks


@pytest.mark.parametrize("show", [False, True])
@pytest.mark.parametrize("starts", [range(0), range(0, 1), range(0, 7, 2)])
def test_every_block_once_in_order(starts, show, capsys):
    assert list(over_blocks(starts, show, "gravity", "block")) == list(starts)
    shown = "gravity" in capsys.readouterr().err
    assert shown == (show and len(starts) > 1)


def test_the_last_bar_stops_tqdms_monitor_thread():
    list(over_blocks(range(5), True, "gravity", "block"))
    assert not [t for t in threading.enumerate() if type(t).__name__ == "TMonitor"]


def test_a_bar_still_shown_keeps_the_monitor(capsys):
    with tqdm(range(3), desc="outer") as outer:
        list(over_blocks(range(5), True, "gravity", "block"))
        monitor = tqdm.monitor
        assert monitor is None or monitor.is_alive()
        list(outer)
    if monitor is not None:
        monitor.exit()
