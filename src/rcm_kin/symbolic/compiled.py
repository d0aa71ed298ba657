"""CasADi functions compiled to C once and cached on disk; interpreted where no compiler is found.

:func:`compiled` generates C for a CasADi function (``Function.generate``), builds a shared
library with the C compiler ``$CC`` (default ``cc``) and loads it with ``casadi.external``. The
library is cached under ``$XDG_CACHE_HOME/rcm-kin/casadi`` (default ``~/.cache/rcm-kin/casadi``),
named by a SHA-256 of the function's serialisation, the CasADi version, the compile command and
the machine (operating system and processor: a home folder shared by machines shares no binaries),
so a changed model, CasADi or compiler builds anew and an unchanged one loads in milliseconds. Each
library has a checksum file beside it (``<library>.sha256``: the SHA-256 of its bytes and its full
key, written before the library is renamed into place); a cached library is used only when the
file's key is the one asked for and its bytes hash as recorded. One that fails (truncated, another
library copied over its name, no checksum file) or does not load is deleted and built once more,
with one warning naming it.
The compiled function evaluates the same expression graph: results agree with the interpreted
function to rounding (the tests hold them to 1e-12). Mapping a compiled function
(``compiled(f).map(n)``) keeps the loop in C; :func:`map_points` evaluates many points through
bound buffers, without CasADi matrices in between. Before generating C, an SX function's common
subexpressions are merged (``casadi.cse``: the same operations on the same values, fewer of them).

Without a C compiler the interpreted function is returned and a
:class:`~rcm_kin.errors.CompilerFallbackWarning` says so (once per compiler setting and process).
:func:`single_call` evaluates one point through CasADi's bound buffers (``Function.buffer``), without
the conversion of NumPy arguments a plain call pays (docs/performance.md).
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import platform
import shlex
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import casadi as ca
import numpy as np

from rcm_kin.atomic import write_text
from rcm_kin.errors import CompilerFallbackWarning, RcmKinError, warn

COMPILE_FLAGS = ("-O2", "-fPIC", "-shared", "-ffp-contract=off")   # no fused multiply-add: as interpreted
CACHE_LIBRARIES = 256     # compiled libraries kept; beyond it the least recently used go


def cache_folder() -> Path:
    """Where compiled functions are kept: ``$XDG_CACHE_HOME/rcm-kin/casadi`` (default ``~/.cache``)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "rcm-kin" / "casadi"


def compiler_command() -> list[str]:
    """The C compiler as a command list: ``$CC`` split like a shell would (default ``cc``)."""
    return shlex.split(os.environ.get("CC") or "cc")


def cache_key(*parts: str) -> str:
    """SHA-256 (hex) of ``parts`` and the machine (``platform.system()``, ``platform.machine()``):
    the name of a cached library, so that a home folder shared by machines shares no binaries."""
    digest = hashlib.sha256()
    for part in (*parts, platform.system(), platform.machine()):
        digest.update(part.encode())
        digest.update(b"\0")
    return digest.hexdigest()


def function_key(fn: ca.Function, command: list[str]) -> str:
    """:func:`cache_key` of the function's serialisation, the CasADi version and the compile command."""
    return cache_key(fn.serialize(), ca.__version__, " ".join(command + list(COMPILE_FLAGS)))


@functools.cache
def _available(compiler: str) -> bool:
    """Whether ``compiler`` runs; if not, warn once that functions run interpreted."""
    if shutil.which(compiler) is not None:
        return True
    _warn(f"no C compiler '{compiler}' found (set CC)")
    return False


@functools.cache
def _warn(reason: str) -> None:
    """A :class:`~rcm_kin.errors.CompilerFallbackWarning` (once per reason and process): functions run interpreted."""
    warn(f"{reason}: CasADi functions run interpreted, slower", CompilerFallbackWarning)


def compiled(fn: ca.Function) -> ca.Function:
    """``fn`` compiled to C and loaded (from the cache when built before), or ``fn`` itself when
    no C compiler is found or the cache folder cannot be written (a
    :class:`~rcm_kin.errors.CompilerFallbackWarning`). Raises
    :class:`RcmKinError` when the compiler fails on the code or the library does not load."""
    return compiled_and_library(fn)[0]


def compiled_and_library(fn: ca.Function) -> tuple[ca.Function, ctypes.CDLL | None]:
    """:func:`compiled` and the library behind it, loaded with ``ctypes`` (None where ``fn`` runs
    interpreted): its C entry points for callers that loop in C (:mod:`rcm_kin.symbolic.points`)."""
    if any(f.is_a("External") for f in fn.find_functions()):    # it calls compiled code already (a bound
        return fn, None                                          # parametric model)
    found = loaded_library(fn)
    return (fn, None) if found is None else (_load(fn.name(), found[0]), found[1])


def loaded_library(fn: ca.Function) -> tuple[Path, ctypes.CDLL] | None:
    """:func:`compiled_library` of ``fn`` and the library loaded (:func:`load_library`); None as it; an
    :class:`RcmKinError` when the compiler fails or the library built anew does not load either."""
    library = compiled_library(fn)
    return None if library is None else load_library(library, lambda: compiled_library(fn), fn.name())


def load_library(library: Path, rebuild: Callable[[], Path | None], name: str) -> tuple[Path, ctypes.CDLL] | None:
    """``library`` loaded with ``ctypes`` (it stays loaded for the process). A cached library that
    does not load (truncated by a full disk or a killed copy, corrupt) is deleted and ``rebuild()``
    once (None from it: None). Raises :class:`RcmKinError` naming ``name`` when the file cannot be
    deleted or the library built anew does not load either."""
    try:
        return library, ctypes.CDLL(str(library))
    except OSError as exc:
        failure = exc
    try:
        library.unlink(missing_ok=True)
        checksum_file(library).unlink(missing_ok=True)
    except OSError as exc:
        raise RcmKinError(f"the compiled {name} does not load ({failure}) and cannot be deleted "
                          f"({exc.strerror})") from None
    library = rebuild()
    if library is None:
        return None
    try:
        return library, ctypes.CDLL(str(library))
    except OSError as exc:
        raise RcmKinError(f"the compiled {name} does not load, even built anew: {exc}") from None


def compiled_library(fn: ca.Function) -> Path | None:
    """The cached shared library of ``fn`` (built first if absent), which exports CasADi's C
    interface under ``fn.name()``: ``int name(const double** arg, double** res, long long* iw,
    double* w, int mem)`` and ``name_work`` for the sizes; None when no C compiler is found or
    the cache folder cannot be written (a warning, as :func:`compiled`)."""
    def source() -> str:
        generator = ca.CodeGenerator(f"{fn.name()}.c", {"with_header": False})
        generator.add(_merged(fn))
        return generator.dump()
    return cached_library(fn.name(), lambda command: function_key(fn, command), source)


def cached_library(name: str, key: Callable[[list[str]], str], source: str | Callable[[], str],
                   flags: tuple[str, ...] = COMPILE_FLAGS) -> Path | None:
    """:func:`build_library` of the C ``source`` with the compiler of :func:`compiler_command`, under
    ``key(command)`` (a :func:`cache_key` with the command and ``flags`` among its parts); None when
    no C compiler is found or the cache folder cannot be written (a
    :class:`~rcm_kin.errors.CompilerFallbackWarning`, once per reason and process)."""
    command = compiler_command()
    if not command or not _available(command[0]):
        return None
    try:
        return build_library(name, key(command), source, command, flags)
    except OSError as exc:
        _warn(f"cannot write the compiled-function cache {cache_folder()} ({exc.strerror})")
        return None


@functools.lru_cache(maxsize=64)
def _load(name: str, library: Path) -> ca.Function:
    return ca.external(name, str(library))


def build_library(name: str, key: str, source: str | Callable[[], str], command: list[str],
                  flags: tuple[str, ...] = COMPILE_FLAGS) -> Path:
    """The shared library ``name_<key>.so`` in the cache folder, compiled from the C ``source``
    (or what ``source()`` returns, called only when the library is not cached) with ``command``
    and ``flags`` first if absent (written atomically, so concurrent processes never
    load a half-written file), its :func:`checksum_file` written before it. A cached library is
    returned only when :func:`library_mismatch` finds none; otherwise it is deleted and built
    anew, with one warning naming it and why. The folder keeps the :data:`CACHE_LIBRARIES` most
    recently used libraries (a use touches the file). A compiler failure is an
    :class:`RcmKinError` with its first line."""
    folder = cache_folder()
    library = folder / f"{name}_{key[:32]}.so"
    if library.exists():
        reason = library_mismatch(library, key)
        if reason is None:
            try:
                os.utime(library)
            except OSError:             # pruned by another process just now: built again below
                pass
            else:
                return library
        else:
            warn(f"the cached library {library} {reason}: deleted and built anew")
            library.unlink(missing_ok=True)
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder) as work:
        path = Path(work) / f"{name}.c"
        path.write_text(source() if callable(source) else source)
        target = Path(work) / library.name
        run = subprocess.run([*command, *flags, str(path), "-o", str(target), "-lm"],
                             capture_output=True, text=True)
        if run.returncode != 0:
            first = (run.stderr.strip().splitlines() or ["no message"])[0]
            raise RcmKinError(f"compiling {name} with {command[0]} failed: {first}")
        write_text(checksum_file(library), f"{_sha256(target)} {key}\n")
        target.replace(library)
    prune_cache(folder, keep=library)
    return library


def checksum_file(library: Path) -> Path:
    """The checksum file beside ``library``: ``<library>.sha256``, one line ``<sha256 of the
    library's bytes> <full cache key>``."""
    return library.with_name(library.name + ".sha256")


def library_mismatch(library: Path, key: str) -> str | None:
    """Why the cached ``library`` must not be used for ``key`` (its :func:`checksum_file` missing
    or unreadable, recorded for another key, or its bytes hashing otherwise: truncated, or
    another library copied over its name), or None when it is the library built for ``key``."""
    try:
        recorded = checksum_file(library).read_text().split()
    except FileNotFoundError:
        return "has no checksum file (built by an older version, or copied in)"
    except (OSError, UnicodeDecodeError) as exc:
        return f"has an unreadable checksum file ({getattr(exc, 'strerror', None) or exc})"
    if len(recorded) != 2 or recorded[1] != key:
        return "has a checksum file for another key"
    try:
        digest = _sha256(library)
    except OSError as exc:
        return f"cannot be read ({exc.strerror})"
    return None if digest == recorded[0] else "does not match its SHA-256 (truncated or overwritten)"


def _sha256(path: Path) -> str:
    """SHA-256 (hex) of the bytes of the file ``path``."""
    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


def prune_cache(folder: Path, keep: Path, limit: int | None = None, pattern: str = "*.so") -> None:
    """Delete the least recently used ``pattern`` files (and their checksum files) in ``folder``
    beyond ``limit`` (default :data:`CACHE_LIBRARIES`), never ``keep``. A library another process has loaded stays valid
    (its mapping outlives the name); one about to be loaded is rebuilt (:func:`loaded_library`)."""
    limit = CACHE_LIBRARIES if limit is None else limit
    libraries = []
    for path in folder.glob(pattern):
        try:
            libraries.append((path.stat().st_mtime, path))
        except OSError:
            continue
    libraries.sort(reverse=True)
    for _, path in libraries[limit:]:
        if path != keep:
            path.unlink(missing_ok=True)
            checksum_file(path).unlink(missing_ok=True)


def _merged(fn: ca.Function) -> ca.Function:
    """An SX function with its common subexpressions merged (``casadi.cse``): the same operations
    on the same values, fewer of them; other functions unchanged."""
    if not fn.is_a("SXFunction"):
        return fn
    args = fn.sx_in()
    return ca.Function(fn.name(), args, ca.cse(fn.call(args)), fn.name_in(), fn.name_out())


def map_points(fn: ca.Function, *args: np.ndarray, chunk: int = 16384) -> tuple[np.ndarray, ...]:
    """``fn`` at N points, ``fn.map`` over chunks of ``chunk`` points through bound buffers (no
    CasADi matrices in between, memory bounded by the chunk and the outputs; the map of an SX or
    compiled function built once per process and size).

    ``args``: arrays (N, nnz_in_i), one row per point (dense inputs). Returns one array per output: (N,)
    for a scalar output, (N, rows) for a column vector, (N, rows, cols) otherwise (zeros filled)."""
    n = len(args[0])
    rows = [np.ascontiguousarray(np.asarray(a, dtype=float).reshape(n, -1)) for a in args]
    for i, a in enumerate(rows):
        if a.shape[1] != fn.nnz_in(i) or not fn.sparsity_in(i).is_dense():
            raise RcmKinError(f"{fn.name()}: input {i} needs {fn.nnz_in(i)} dense values per point")
    nonzeros = [np.empty((n, fn.nnz_out(i))) for i in range(fn.n_out())]
    mapped = {}
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        if stop - start not in mapped:
            mapped[stop - start] = (fn.map(stop - start) if fn.is_a("MXFunction")    # a bound model's: not kept
                                    else _mapped(fn, stop - start)).buffer()
        buffer, trigger = mapped[stop - start]
        views = [a[start:stop] for a in rows] + [nz[start:stop] for nz in nonzeros]
        for i, v in enumerate(views[:len(rows)]):
            buffer.set_arg(i, memoryview(v))
        for i, v in enumerate(views[len(rows):]):
            buffer.set_res(i, memoryview(v))
        trigger()
    return tuple(_points_layout(fn.sparsity_out(i), nz) for i, nz in enumerate(nonzeros))


@functools.lru_cache(maxsize=128)
def _mapped(fn: ca.Function, n: int) -> ca.Function:
    """``fn.map(n)``, kept for the process: CasADi builds a map in time linear in ``n`` (about as long
    as evaluating it) and drops it with its last user."""
    return fn.map(n)


def map_points_into(fn: ca.Function, args: Sequence[np.ndarray], outs: Sequence[np.ndarray],
                    chunk: int = 4096) -> None:
    """``fn`` at N points, written into ``outs``: the numbers of :func:`map_points`, without building a
    map or copying an output per call.

    ``args``: (N, nnz_in_i) and ``outs``: (N, nnz_out_i) C-contiguous float64 arrays, one row per
    point (dense inputs; the outputs' nonzeros, column-major). The points are evaluated by maps of
    ``chunk`` points and, for the rest, of power-of-two sizes, each map built once per process."""
    if chunk < 1:
        raise RcmKinError(f"{fn.name()}: chunk must be at least 1 point, got {chunk}", parameter="chunk")
    n = check_point_arrays(fn, args, outs)
    start = 0
    while start < n:
        size = chunk if n - start >= chunk else 1 << ((n - start).bit_length() - 1)
        buffer, trigger = _mapped(fn, size).buffer()
        for _ in range((n - start) // size if size == chunk else 1):
            for i, a in enumerate(args):
                buffer.set_arg(i, memoryview(a[start:start + size]))
            for i, o in enumerate(outs):
                buffer.set_res(i, memoryview(o[start:start + size]))
            trigger()
            start += size


def check_point_arrays(fn: ca.Function, args: Sequence[np.ndarray], outs: Sequence[np.ndarray]) -> int:
    """The number of points N of ``args`` and ``outs`` for ``fn`` (:func:`map_points_into`), or an
    error unless they are C-contiguous float64 arrays (N, nnz) of its dense inputs and (writeable)
    outputs' nonzeros."""
    if len(args) != fn.n_in() or len(outs) != fn.n_out():
        raise RcmKinError(f"{fn.name()}: takes {fn.n_in()} inputs and gives {fn.n_out()} outputs, "
                          f"got {len(args)} and {len(outs)}")
    arrays = [(a, fn.nnz_in(i), f"input {i}", fn.sparsity_in(i).is_dense()) for i, a in enumerate(args)]
    arrays += [(o, fn.nnz_out(i), f"output {i}", getattr(o, "flags", None) is not None and o.flags.writeable)
               for i, o in enumerate(outs)]
    n = len(arrays[0][0]) if arrays else 0
    for a, nnz, what, ok in arrays:
        if not (ok and isinstance(a, np.ndarray) and a.dtype == np.float64 and a.shape == (n, nnz)
                and a.flags.c_contiguous):
            raise RcmKinError(f"{fn.name()}: {what} needs a C-contiguous float64 array ({n}, {nnz}) "
                              "(dense inputs, writeable outputs)")
    return n


def _points_layout(sparsity: ca.Sparsity, nz: np.ndarray) -> np.ndarray:
    """(N, nnz) nonzeros per point -> (N,), (N, rows) or (N, rows, cols) dense."""
    rows, cols = sparsity.size1(), sparsity.size2()
    if sparsity.is_dense():
        if cols == 1:
            return nz[:, 0] if rows == 1 else nz
        return nz.reshape(len(nz), cols, rows).transpose(0, 2, 1)
    r, c = (np.array(x, dtype=int) for x in sparsity.get_triplet())
    out = np.zeros((len(nz), rows, cols))
    out[:, r, c] = nz
    return out[:, :, 0] if cols == 1 else out


def single_call(fn: ca.Function) -> Callable[..., tuple[np.ndarray, ...]]:
    """A fast evaluator of ``fn`` at one point: ``call(*args) -> tuple`` of dense float arrays
    shaped like ``fn``'s outputs (vectors flat). Arguments are copied into buffers bound once;
    the returned arrays are fresh copies."""
    buffer, trigger = fn.buffer()
    args = [np.zeros(fn.nnz_in(i)) for i in range(fn.n_in())]
    results = [np.zeros(fn.nnz_out(i)) for i in range(fn.n_out())]
    for i, a in enumerate(args):
        if not fn.sparsity_in(i).is_dense():
            raise RcmKinError(f"{fn.name()}: single_call needs dense inputs")
        buffer.set_arg(i, memoryview(a))
    for i, r in enumerate(results):
        buffer.set_res(i, memoryview(r))
    layouts = [_dense_layout(fn.sparsity_out(i)) for i in range(fn.n_out())]

    def call(*values) -> tuple[np.ndarray, ...]:
        for a, v in zip(args, values, strict=True):
            a[:] = np.ravel(v, order="F")
        trigger()
        return tuple(layout(r) for layout, r in zip(layouts, results))

    call.buffers = (buffer, trigger)   # keeps CasADi's buffer alive with the closure
    return call


def _dense_layout(sparsity: ca.Sparsity) -> Callable[[np.ndarray], np.ndarray]:
    """Nonzeros (column-major) -> a dense array: flat for a column vector, else (rows, cols)."""
    rows, cols = sparsity.size1(), sparsity.size2()
    if sparsity.is_dense():
        if cols == 1:
            return lambda nz: nz.copy()
        return lambda nz: nz.reshape(cols, rows).T.copy()
    r, c = (np.array(x, dtype=int) for x in sparsity.get_triplet())

    def scatter(nz: np.ndarray) -> np.ndarray:
        out = np.zeros((rows, cols))
        out[r, c] = nz
        return out[:, 0] if cols == 1 else out
    return scatter
