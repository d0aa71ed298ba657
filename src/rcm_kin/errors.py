"""The one exception type for user errors (bad input, unreachable targets, bad files)."""


class RcmKinError(ValueError):
    """A request rcm_kin cannot satisfy; the message says what was wrong and what to do.

    The CLI prints it as one line ``error: <message>`` and exits with status 2.
    """
