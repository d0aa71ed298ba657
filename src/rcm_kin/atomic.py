"""Files written whole or not at all: every file rcm_kin writes goes through this module.

A file is written to a temporary name in its own folder (``.<stem>.<random>.partial<suffix>``,
created exclusively, with the permissions a plain write would give), flushed and fsynced, then
renamed onto its final name with :func:`os.replace`, which is atomic on one file system. A write
that fails or is interrupted (an exception, ``KeyboardInterrupt``, ``SystemExit``) removes the
temporary: no file appears under the final name, and a file already there is left as it was.

An output that is a symbolic link is written through only when the link's target stays in the
output's folder; a link leading out of it is an :class:`~rcm_kin.errors.RcmKinError`.

**Owned outputs.** A run (the command line's) may :func:`claim` its outputs: a folder it writes
into, or a single file. A claimed folder is locked for the run (``flock`` on the folder: a second
run claiming it is refused at once, never two runs claiming success for one result), is cleared of
unfinished temporaries when the claim ends (a worker process stopped outright leaves its own), and
keeps a manifest (``.rcm-kin-outputs.json``) of the files rcm_kin wrote there, with their size and
modification time. While a claim is open, a write under the claimed folder replaces a file only
when rcm_kin wrote it and it is unchanged since, or when the claim was made with ``force``; a
claimed single file that appears (or changes) after the claim, while the run works, is not
replaced without ``force`` (another run wrote it). Without a claim (a library call) a write
replaces what is there, as a plain write would, but atomically.

:func:`atomic_open` gives a text or binary stream; :func:`atomic_path` gives a temporary path for
libraries that write by path (matplotlib's ``savefig``, ``np.savetxt``); :func:`write_text` and
:func:`write_bytes` are the one-call forms.
"""

import contextlib
import fcntl
import json
import os
import secrets
import signal
import stat
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from rcm_kin.errors import RcmKinError, read_bounded

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
    """Create a new empty temporary file beside ``final`` (exclusively: never an existing name),
    named with the tag of the claim it is under, if any (so the claim clears only its own)."""
    claim = _claim_of(final) if _CLAIMS else None
    tag = claim.tag if claim is not None else ""
    for _ in range(100):
        temporary = final.with_name(f".{final.stem}.{tag}{secrets.token_hex(4)}{PARTIAL}{final.suffix}")
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


_STOPPED: list[str] = []


def stop_writes(reason: str) -> None:
    """From now on, in this process, no write is committed: each raises an RcmKinError giving
    ``reason`` (and leaves no file). The command line calls it on SIGTERM, so that a run that
    carries on for a while (a signal landing where an exception is swallowed) writes nothing more."""
    _STOPPED.append(reason)


def _commit(temporary: Path, final: Path) -> None:
    """Rename ``temporary`` onto ``final`` (an existing file's permissions kept; the folder is not
    fsynced: the rename is atomic for every process, and after a power cut the file is the old or
    the new one, whole, as its data was fsynced first); under an open :func:`claim`, only where the
    claim admits it (:meth:`Claim.admit`); never after :func:`stop_writes`."""
    if _STOPPED:
        raise RcmKinError(f"{final} not written: {_STOPPED[0]}")
    claim = _claim_of(final)
    exclusive = claim is not None and claim.admit(final.resolve())
    with contextlib.suppress(FileNotFoundError):
        os.chmod(temporary, stat.S_IMODE(os.stat(final).st_mode))
    if exclusive:
        _link_new(temporary, final)
    else:
        os.replace(temporary, final)
    if claim is not None:
        claim.record(final.resolve())


MANIFEST = ".rcm-kin-outputs.json"
"""The manifest of a claimed folder: the files rcm_kin wrote there (relative path -> [size, mtime_ns]).
Beside it while a run works, ``<MANIFEST>.journal``: the files committed so far, one per line (forked
workers append theirs)."""


@dataclass
class Claim:
    """An output a run owns while it works: a folder (``path`` a folder, resolved, reached as
    ``lexical``; locked by ``lock``, with the manifest ``owned`` of the files rcm_kin wrote there)
    or one file (``before``: its size and modification time when claimed, None when it did not
    exist). ``written``: the files this process committed; ``tag``: marks the claim's temporaries."""

    path: Path
    force: bool
    folder: bool
    lexical: Path | None = None
    owned: dict = field(default_factory=dict)
    before: tuple | None = None
    lock: int | None = None
    written: set = field(default_factory=set)
    tag: str = field(default_factory=lambda: secrets.token_hex(3))

    def covers(self, final: Path) -> bool:
        """Whether a write to ``final`` (a resolved path) is under this claim."""
        return final.is_relative_to(self.path) if self.folder else final == self.path

    def admit(self, final: Path) -> bool:
        """Allow the commit of ``final`` or refuse it (RcmKinError); True when it must create the
        file exclusively (nothing may be there when it lands)."""
        now = _signature(final)
        if self.force or final in self.written:
            return False
        if self.folder:
            if now is None:
                return True
            if self.owned.get(final.relative_to(self.path).as_posix()) == list(now):
                return False
            raise RcmKinError(f"{final} exists and rcm-kin did not write it (or it changed since): "
                              "choose another output folder, move the file, or add `force`", parameter="force")
        if now is None and self.before is None:
            return True
        if now is not None and now == self.before:
            return False
        raise RcmKinError(f"{final} was written by another run while this one worked: "
                          "nothing replaced; choose another output file or add `force`", parameter="force")

    def record(self, final: Path) -> None:
        """Note ``final`` (resolved) as committed under this claim; a folder's in its journal too,
        which the run's forked workers share."""
        self.written.add(final)
        if self.folder:
            with open(self.path / (MANIFEST + ".journal"), "a") as fh:
                fh.write(final.relative_to(self.path).as_posix() + "\n")


_CLAIMS: list[Claim] = []


@contextlib.contextmanager
def claim(path: str | Path, *, folder: bool, force: bool = False) -> Iterator[Claim]:
    """Own ``path`` (a folder, created if missing, when ``folder``; else one file) until the block
    ends: see the module's "Owned outputs". A folder another run has claimed is an RcmKinError; a
    folder the claim created is removed again if nothing was written in it. A write under the
    folder that a link leads out of it is an RcmKinError."""
    path = Path(path)
    if not folder:
        final = final_target(path).resolve()
        c = Claim(final, force, False, before=_signature(final))
        with _open_claim(c):
            yield c
        return
    created = not path.exists()
    try:
        path.mkdir(parents=True, exist_ok=True)
        lock = os.open(path, os.O_RDONLY)
    except OSError as exc:
        raise RcmKinError(f"cannot create the output folder {path}: {exc.strerror}") from None
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(lock)
        raise RcmKinError(f"another run is writing to {path}: wait for it to end or choose another folder") from None
    c = Claim(path.resolve(), force, True, lexical=Path(os.path.abspath(path)), owned=_read_manifest(path), lock=lock)
    try:
        with _open_claim(c):
            yield c
    finally:
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})   # the clean-up ends
        try:
            with contextlib.suppress(OSError):
                _write_manifest(c)
            _remove_partials(c)
            with contextlib.suppress(OSError):
                if created and not any(c.path.iterdir()):      # a run that wrote nothing leaves no new folder
                    c.path.rmdir()
            os.close(lock)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


def _remove_partials(c: Claim) -> None:
    """Remove the claim's own unfinished writes (a worker process stopped outright leaves its
    temporary): those named with its tag, nobody else's."""
    for path in c.path.rglob(f".*.{c.tag}*{PARTIAL}*"):
        with contextlib.suppress(OSError):
            path.unlink()


@contextlib.contextmanager
def _open_claim(c: Claim) -> Iterator[None]:
    _CLAIMS.append(c)
    try:
        yield
    finally:
        _CLAIMS.remove(c)


def _claim_of(final: Path) -> Claim | None:
    """The innermost open claim covering ``final``, if any; a path under a claimed folder that a
    link leads out of it is an RcmKinError."""
    if not _CLAIMS:
        return None
    resolved, lexical = final.resolve(), Path(os.path.abspath(final))
    for c in reversed(_CLAIMS):
        if c.covers(resolved):
            return c
        if c.folder and lexical.is_relative_to(c.lexical):
            raise RcmKinError(f"{final} leads out of the output folder {c.lexical} through a link (to {resolved}): "
                              "remove the link or choose another output")
    return None


def _signature(path: Path) -> tuple[int, int] | None:
    """(size, mtime_ns) of the file at ``path``, None when there is none."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return None
    return st.st_size, st.st_mtime_ns


def _read_manifest(folder: Path) -> dict:
    """The files a claimed folder's manifest says rcm_kin wrote (empty when none or unreadable)."""
    try:
        owned = json.loads(read_bounded(folder / MANIFEST, "manifest")).get("files", {})
    except (OSError, ValueError, AttributeError):
        return {}
    return owned if isinstance(owned, dict) else {}


def _write_manifest(c: Claim) -> None:
    """Record in the folder's manifest every file this run committed there (this process's and its
    forked workers', from the journal), beside the earlier runs' still unchanged; also after a
    failure (the files committed before it are rcm_kin's)."""
    journal = c.path / (MANIFEST + ".journal")
    try:
        names = set(journal.read_text().split("\n")) - {""}
        journal.unlink()
    except FileNotFoundError:
        names = set()
    names |= {final.relative_to(c.path).as_posix() for final in c.written}
    files = {name: sig for name, sig in c.owned.items() if list(_signature(c.path / name) or ()) == sig}
    files.update({name: list(sig) for name in names if (sig := _signature(c.path / name)) is not None})
    if not files and not (c.path / MANIFEST).exists():
        return
    temporary = _reserve(c.path / MANIFEST)
    try:
        temporary.write_text(json.dumps({"written_by": "rcm-kin", "files": dict(sorted(files.items()))}, indent=1))
        os.replace(temporary, c.path / MANIFEST)
    except BaseException:
        with contextlib.suppress(OSError):
            temporary.unlink()
        raise


def _link_new(temporary: Path, final: Path) -> None:
    """Move ``temporary`` to ``final`` only if nothing is there (a hard link, then the temporary
    removed): a file that appeared meanwhile is an RcmKinError, never replaced."""
    try:
        os.link(temporary, final)
    except FileExistsError:
        raise RcmKinError(f"{final} was written by another run while this one worked: "
                          "nothing replaced; choose another output", parameter="force") from None
    except OSError:                 # a file system without hard links: the plain rename
        os.replace(temporary, final)
        return
    temporary.unlink()
