"""The one exception type for user errors (bad input, unreachable targets, bad files), and the
file helpers that turn the operating system's errors into it."""

import tomllib
from pathlib import Path


class RcmKinError(ValueError):
    """A request rcm_kin cannot satisfy; the message says what was wrong and what to do.

    The CLI prints it as one line ``error: <message>`` and exits with status 2.
    """


class ParameterFileError(RcmKinError):
    """A parameter file holds a key, type or value outside its schema (the file and key are named)."""


class JointLimitError(RcmKinError):
    """A pose (given, or reached by a simulation) outside the joints' limits: refused, not computed."""


class WorkLimitError(RcmKinError):
    """A request that would need more memory or time than the stated bound (the message says how much)."""


class LogDataError(RcmKinError):
    """A measured log with missing or non-finite values where a fit needs numbers."""


class NonFiniteResultError(RcmKinError):
    """A computation gave NaN or an infinity: the inputs are outside what the model can compute."""


def read_toml(path: Path, what: str) -> dict:
    """The parsed TOML file ``path``; a missing or malformed file is an RcmKinError naming ``what``."""
    try:
        return tomllib.loads(Path(path).read_text())
    except FileNotFoundError:
        raise RcmKinError(f"no {what} at {path}") from None
    except OSError as exc:
        raise RcmKinError(f"cannot read the {what} {path}: {exc.strerror}") from None
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise RcmKinError(f"{path}: not valid TOML ({exc})") from None


def output_folder(path) -> Path:
    """``path`` as a created folder; an OSError becomes an RcmKinError naming the folder."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RcmKinError(f"cannot create the output folder {out}: {exc.strerror}") from None
    return out


class RcmKinWarning(UserWarning):
    """Something the user should know that does not stop the computation (the CLI prints each as
    one line ``warning: ...`` on stderr)."""
