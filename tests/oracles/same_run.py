"""The one statement of "the compiled engine equals the readable loop tick for tick" that the
simulation tests hold every engine pair to."""

from __future__ import annotations

import numpy as np


def assert_same_run(fast, slow) -> None:
    """``fast`` (compiled) and ``slow`` (readable) are the same run: the engines named, the true
    angles within 1e-9 rad (1e-9 m), the encoder readings and the sent PWM identical, the
    commands within 1e-9 counts, and a controller that acted."""
    assert fast.engine == "compiled" and slow.engine == "readable"
    assert fast.controller == slow.controller and fast.position.shape == slow.position.shape
    np.testing.assert_allclose(fast.position[:, :2], slow.position[:, :2], rtol=0, atol=np.degrees(1e-9))
    np.testing.assert_allclose(fast.position[:, 2], slow.position[:, 2], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(fast.measured, slow.measured)
    np.testing.assert_array_equal(fast.pwm, slow.pwm)
    np.testing.assert_allclose(fast.command, slow.command, rtol=0, atol=1e-9)
    assert np.ptp(fast.pwm[:, 1]) > 10                             # the controller acted
