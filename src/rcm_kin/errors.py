"""The one exception type for user errors (bad input, unreachable targets, bad files), and the
TOML reader every parameter file goes through."""

import tomllib
from pathlib import Path


class RcmKinError(ValueError):
    """A request rcm_kin cannot satisfy; the message says what was wrong and what to do.

    The CLI prints it as one line ``error: <message>`` and exits with status 2.
    """


def read_toml(path: Path, what: str) -> dict:
    """The parsed TOML file ``path``; a missing or malformed file is an RcmKinError naming ``what``."""
    try:
        return tomllib.loads(Path(path).read_text())
    except FileNotFoundError:
        raise RcmKinError(f"no {what} at {path}") from None
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise RcmKinError(f"{path}: not valid TOML ({exc})") from None
