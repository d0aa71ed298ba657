"""Files written whole or not at all: every file rcm_kin writes goes through this module.

A file is written to a temporary name in its own folder (``.<stem>.<random>.partial<suffix>``,
created exclusively, with the permissions a plain write would give), flushed and fsynced, then
renamed onto its final name with :func:`os.replace`, which is atomic on one file system. A write
that fails or is interrupted (an exception, ``KeyboardInterrupt``, ``SystemExit``) removes the
temporary: no file appears under the final name, and a file already there is left as it was.

An output that is a symbolic link is written through only when the link's target stays in the
output's folder; a link leading out of it is an :class:`~rcm_kin.errors.RcmKinError`.

:func:`atomic_open` gives a text or binary stream; :func:`atomic_path` gives a temporary path for
libraries that write by path (matplotlib's ``savefig``, ``np.savetxt``); :func:`write_text` and
:func:`write_bytes` are the one-call forms.
"""

import contextlib
import os
import secrets
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from rcm_kin.errors import RcmKinError

PARTIAL = ".partial"
"""The marker in a temporary's name: a file named ``.<stem>.<random>.partial<suffix>`` is an
unfinished write (left behind only when the process was killed outright, e.g. by SIGKILL)."""


def final_target(path: str | Path) -> Path:
    """The file a write to ``path`` replaces: ``path`` itself, or the target of the symbolic link
    ``path`` when that target is in ``path``'s folder. A link whose target leaves the folder is an
    RcmKinError (outputs never follow a link out of their folder)."""
    path = Path(path)
    if not path.is_symlink():
        return path
    folder, target = path.parent.resolve(), path.resolve()
    if target.parent != folder:
        raise RcmKinError(f"{path} is a link to {target}, outside its folder {path.parent}: "
                          f"remove the link or choose another output")
    return target


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path in ``path``'s folder with ``path``'s suffix (a created, empty file) to
    write by path; when the block ends normally the file is fsynced and renamed onto ``path``
    (see :func:`final_target` for links); when it raises, the temporary is removed and ``path``
    is untouched. An OSError creating the temporary names ``path``."""
    final = final_target(path)
    temporary = _reserve(final)
    try:
        yield temporary
        _sync(temporary)
        _commit(temporary, final)
    except BaseException:
        with contextlib.suppress(OSError):
            temporary.unlink()
        raise


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w", *, encoding: str | None = None,
                newline: str | None = None) -> Iterator[IO]:
    """An open stream (``mode`` ``"w"`` for text, ``"wb"`` for bytes) whose content replaces the file
    ``path`` when the block ends normally, and is discarded when it raises (:func:`atomic_path`)."""
    if mode not in ("w", "wb"):
        raise RcmKinError(f"atomic_open writes a new file: mode 'w' or 'wb', not {mode!r}", parameter="mode")
    with atomic_path(path) as temporary:
        if mode == "wb":
            with open(temporary, "wb") as fh:
                yield fh
        else:
            with open(temporary, "w", encoding=encoding, newline=newline) as fh:
                yield fh


def write_text(path: str | Path, text: str, *, encoding: str | None = None, newline: str | None = None) -> Path:
    """Write ``text`` to ``path`` atomically (as :meth:`pathlib.Path.write_text` would write it);
    the path written."""
    with atomic_open(path, "w", encoding=encoding, newline=newline) as fh:
        fh.write(text)
    return Path(path)


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; the path written."""
    with atomic_open(path, "wb") as fh:
        fh.write(data)
    return Path(path)


def _reserve(final: Path) -> Path:
    """Create a new empty temporary file beside ``final`` (exclusively: never an existing name)."""
    for _ in range(100):
        temporary = final.with_name(f".{final.stem}.{secrets.token_hex(4)}{PARTIAL}{final.suffix}")
        try:
            fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)   # the umask applies
        except FileExistsError:
            continue
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror, str(final)) from None
        os.close(fd)
        return temporary
    raise OSError(f"no free temporary name beside {final}")


def _sync(temporary: Path) -> None:
    """Flush ``temporary``'s content to the disk (before the rename makes it the final file)."""
    fd = os.open(temporary, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _commit(temporary: Path, final: Path) -> None:
    """Rename ``temporary`` onto ``final`` (an existing file's permissions kept), then fsync the folder."""
    with contextlib.suppress(FileNotFoundError):
        os.chmod(temporary, stat.S_IMODE(os.stat(final).st_mode))
    os.replace(temporary, final)
    with contextlib.suppress(OSError):      # not every system opens a folder (Windows): the rename stands
        fd = os.open(final.parent, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
