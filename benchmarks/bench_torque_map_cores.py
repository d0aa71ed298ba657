"""``rcm-kin torque-map psm --out DIR`` (61 x 61, three figures) on two cores, from CPU times: what
its wall time is on a machine whose two cores are free, measured when they are not (issue 30).

The command runs in a fresh process with :func:`rcm_kin.plotting.run_apart` timed: the process's
CPU seconds up to the first fork (the interpreter, the CLI with Pinocchio, the maths, matplotlib's
import), after it (the insertion curves and the tables, and a second fork), and each forked
child's (the heat maps; the trend curves). Its critical path on two cores is the CPU up to the
fork plus the parts after it shared on two cores: the longest part, or half their sum if that is
more; against ``python -c "import pinocchio"``'s CPU seconds in the same rounds (best of
``--repeats`` each, interleaved). ``--against SRC``: the same command with ``PYTHONPATH=SRC``
(e.g. /work/main/src), whose critical path is its whole CPU time when it draws in one process.

    python benchmarks/bench_torque_map_cores.py [--repeats 7] [--against /work/main/src]
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import tempfile
from pathlib import Path

from common import fresh_run

SRC = str(Path(__file__).resolve().parents[1] / "src")
TIMED = """
import json, os, sys, time
from rcm_kin import plotting
from rcm_kin.cli import main
record, out = sys.argv[1], sys.argv[2]
run = getattr(plotting, "run_apart", None)
depth = []
def timed(forked, here, *args):
    def child():
        value = forked()
        with open(record + ".child", "a") as fh:
            fh.write(f"{time.process_time()}\\n")       # a forked child's clock starts at its fork
        return value
    start = time.process_time()
    depth.append(start)
    try:
        return run(child, here, *args)
    finally:
        depth.pop()
        if not depth:                                    # the first fork's: the CPU up to it and after it here
            with open(record, "w") as fh:
                json.dump({"fork": start, "after": time.process_time() - start}, fh)
if run is not None:
    plotting.run_apart = timed
code = main(["torque-map", "psm", "--out", out])
sys.exit(code)
"""


def cpu_of(args: list[str], src: str) -> float:
    """CPU seconds (user + system, children included) of ``python args`` with ``src`` first on the path."""
    return fresh_run(args, src)[1]


def critical_path(src: str, folder: str, k: int) -> tuple[float, float, dict]:
    """(critical path, whole CPU, its parts) of one fresh ``torque-map`` run with ``src``."""
    record = Path(folder) / f"record{k}.json"
    whole = cpu_of(["-c", TIMED, str(record), f"{folder}/maps{k}"], src)
    child = Path(str(record) + ".child")
    if not record.exists() or not child.exists():           # drawn in one process: all of it on one core
        return whole, whole, {}
    parts = json.loads(record.read_text()) | {"children": [float(x) for x in child.read_text().split()]}
    after = [parts["after"], *parts["children"]]
    return parts["fork"] + max(max(after), sum(after) / 2), whole, parts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--against", help="another checkout's src folder, run in the same rounds")
    args = parser.parse_args()
    sources = {"this": SRC} | ({"against": args.against} if args.against else {})
    load = os.getloadavg()[0]
    pinocchio, best = float("inf"), {label: (float("inf"), float("inf"), {}) for label in sources}
    runs = itertools.count()
    with tempfile.TemporaryDirectory() as folder:
        for _ in range(args.repeats):             # interleaved: the machine's load falls on all alike
            pinocchio = min(pinocchio, cpu_of(["-c", "import pinocchio"], SRC))
            for label, src in sources.items():
                best[label] = min(best[label], critical_path(src, folder, next(runs)), key=lambda r: r[0])
    print(f"torque-map psm --out (61 x 61, figures), CPU seconds, best of {args.repeats} (load average {load:.2f} "
          f"before, {os.getloadavg()[0]:.2f} after); import pinocchio {pinocchio:.3f} s")
    for label, (path, whole, parts) in best.items():
        children = ", ".join(f"{x:.3f}" for x in parts.get("children", ()))
        detail = (f" = {parts['fork']:.3f} to the fork, then {parts['after']:.3f} here and {children} in the "
                  "children on two cores") if parts else " (one process)"
        print(f"  {label:8} critical path {path:.3f} s = {path / pinocchio:.2f}x{detail}; all CPU {whole:.3f} s = "
              f"{whole / pinocchio:.2f}x")


if __name__ == "__main__":
    main()
