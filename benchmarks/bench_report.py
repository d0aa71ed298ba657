"""`rcm-kin report` end to end, as the README runs it, and per piece of the report.

- The README's command (``rcm-kin report --out DIR``) in a subprocess, ``--repeats`` times: wall
  time, and the CPU time of the command and its pool (user + system, its children included),
  with the load average before and after (other work on the machine slows the wall time, less so
  the CPU time).
- Per piece (``--pieces``): the report's pieces (``rcm_kin.report.report_jobs``) in the report's
  own pool on the machine's cores (``run_jobs``): each piece's wall time in its worker, which
  worker ran it, and the busiest worker's total (the critical path of the pool's schedule).
- Each piece alone (``--alone``): in a process forked from one that imported what the report
  imports before its pool forks (``rcm_kin.report.preload``), one after the other: its CPU seconds
  and those of its figures' ``savefig`` (drawing and PNG), and the parent's own imports; the sum
  over the pieces, halved, is what the pool's two workers cannot go under on 2 cores.
- ``--against FOLDER``: the content of the last report written against a report written before
  (e.g. by an older commit): index.html and every JSON, CSV, header and MJCF byte for byte; the
  meshcat pages command by command with the scene's random object ids set aside and numbers to
  1e-9 relative; the PNG figures pixel by pixel. Exit status 1 when they differ.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/bench_report.py --repeats 3 --pieces [--alone]``.
"""

from __future__ import annotations

import argparse
import base64
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import common  # noqa: E402,F401  (OPENBLAS_NUM_THREADS=1)

UUID = re.compile(r"^[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}$")


def report_command(out: Path) -> list[str]:
    """The README's command: the venv's ``rcm-kin`` next to this Python, else ``python -m rcm_kin.cli``."""
    script = Path(sys.executable).with_name("rcm-kin")
    return ([str(script)] if script.exists() else [sys.executable, "-m", "rcm_kin.cli"]) + ["report", "--out",
                                                                                                str(out)]


def end_to_end(out: Path) -> tuple[float, float]:
    """Wall and CPU seconds (the command and its children) of one report into a fresh ``out``."""
    shutil.rmtree(out, ignore_errors=True)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    run = subprocess.run(report_command(out), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if run.returncode != 0:
        raise SystemExit(f"the report failed: {run.stderr.strip()}")
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def pieces(out: Path) -> None:
    """Each piece's wall time in the report's pool, by worker."""
    from rcm_kin.parallel import machine_workers
    from rcm_kin.report import report_jobs, run_jobs

    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    workers = min(4, machine_workers())
    start = time.perf_counter()
    results = run_jobs(report_jobs(out, None, 61), workers)
    wall = time.perf_counter() - start
    busy: dict[int, float] = {}
    print(f"pieces in the report's pool ({workers} workers): {wall:.2f} s wall")
    for label, r in results.items():
        busy[r.worker] = busy.get(r.worker, 0.0) + r.seconds
        print(f"  {label:32s} {r.seconds:6.2f} s  worker {r.worker}")
    print("  busiest worker: {:.2f} s of pieces; all workers: {:.2f} s".format(max(busy.values()), sum(busy.values())))


def alone(out: Path) -> None:
    """Each piece's CPU seconds (and its figures') in a process of its own forked after the preload."""
    from matplotlib.figure import Figure

    start = time.process_time()
    from rcm_kin.report import preload, report_jobs

    jobs = report_jobs(out, None, 61)
    preload()
    print(f"each piece alone, CPU s (the parent's imports and preload {time.process_time() - start:.2f} s):")
    savefig, total = Figure.savefig, np.zeros(2)

    def timed_savefig(fig, *arguments, **options):
        begin = time.process_time()
        savefig(fig, *arguments, **options)
        drawn[0] += time.process_time() - begin

    Figure.savefig = timed_savefig
    out.mkdir(parents=True, exist_ok=True)
    for job in jobs:
        drawn = [0.0]
        read, write = os.pipe()
        if os.fork() == 0:                  # the piece in a fresh worker, as the pool's
            begin = time.process_time()
            job.function(*job.arguments)
            os.write(write, f"{time.process_time() - begin} {drawn[0]}".encode())
            os._exit(0)
        os.wait()
        cpu, figures = map(float, os.read(read, 100).split())
        total += cpu, figures
        print(f"  {job.label:32s} {cpu:5.2f} s, figures {figures:5.2f} s")
    Figure.savefig = savefig
    print(f"  all pieces: {total[0]:.2f} s, figures {total[1]:.2f} s")


def meshcat_commands(path: Path) -> list:
    """The commands of a meshcat page (msgpack), every object id replaced by its order of appearance."""
    import umsgpack

    ids: dict[str, str] = {}

    def plain(value):
        if isinstance(value, dict):
            return {plain(k): plain(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [plain(v) for v in value]
        if isinstance(value, str) and UUID.match(value):
            return ids.setdefault(value, f"id{len(ids)}")
        return value

    blobs = re.findall(r'load\("([A-Za-z0-9+/=]+)"\);', path.read_text())
    return [plain(umsgpack.unpackb(base64.b64decode(b))) for b in blobs]


def same_commands(a, b, rtol: float = 1e-9) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_commands(a[k], b[k], rtol) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same_commands(x, y, rtol) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        return a == b or abs(a - b) <= rtol * max(abs(a), abs(b))
    if isinstance(a, bytes) and isinstance(b, bytes) and len(a) == len(b) and len(a) % 4 == 0 and a != b:
        x, y = np.frombuffer(a, np.float32), np.frombuffer(b, np.float32)    # meshcat's packed float32 arrays
        return bool(np.allclose(x, y, rtol=1e-6, atol=0.0))
    return a == b


def compare(new: Path, old: Path) -> bool:
    """Whether the report in ``new`` has the content of the one in ``old`` (see the module's doc)."""
    from PIL import Image

    names = sorted(str(p.relative_to(old)) for p in old.rglob("*") if p.is_file())
    found = sorted(str(p.relative_to(new)) for p in new.rglob("*") if p.is_file())
    ok = names == found
    if not ok:
        print(f"  files differ: only before {sorted(set(names) - set(found))}, "
              f"only now {sorted(set(found) - set(names))}")
    for name in sorted(set(names) & set(found)):
        a, b = old / name, new / name
        if name.endswith(".png"):
            x, y = np.asarray(Image.open(a)), np.asarray(Image.open(b))
            same = x.shape == y.shape and np.array_equal(x, y)
            how = "pixels"
        elif name.endswith("view.html") or name.endswith("animation.html"):
            same = same_commands(meshcat_commands(a), meshcat_commands(b))
            how = "meshcat commands"
        else:
            same = a.read_bytes() == b.read_bytes()
            how = "bytes"
        print(f"  {'same' if same else 'DIFFERENT':9s} ({how}) {name}")
        ok &= same
    return ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--pieces", action="store_true", help="also each piece's time in the report's pool")
    parser.add_argument("--alone", action="store_true", help="also each piece's CPU alone in a forked process")
    parser.add_argument("--keep", type=Path, help="write the report here (default: a temporary folder)")
    parser.add_argument("--against", type=Path, help="compare the report's content with this report folder")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        out = args.keep or Path(scratch) / "report"
        print(f"command: {' '.join(report_command(out))}")
        print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        runs = [end_to_end(out) for _ in range(args.repeats)]
        for k, (wall, cpu) in enumerate(runs):
            print(f"  run {k + 1}: {wall:6.2f} s wall, {cpu:6.2f} s CPU")
        walls = [w for w, _ in runs]
        print(f"wall: best {min(walls):.2f} s, median {float(np.median(walls)):.2f} s")
        print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        ok = compare(out, args.against) if args.against else True
        if args.pieces:
            pieces(Path(scratch) / "pieces")
        if args.alone:
            alone(Path(scratch) / "alone")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
