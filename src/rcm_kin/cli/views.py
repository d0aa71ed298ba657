"""``view`` and ``report``: a robot in meshcat or matplotlib, and the HTML report of the main job."""

from __future__ import annotations

from pathlib import Path

from rcm_kin.atomic import MANIFEST
from rcm_kin.cli.common import RAW, add_json, any_robot, count, emit, joint_values, path_text, progress_wanted
from rcm_kin.cli.outputs import FOLDER_FORCE, add_force, new_folder, new_output
from rcm_kin.cli.packages import add_package_dirs, package_dirs
from rcm_kin.errors import RcmKinError
from rcm_kin.model import load_robot
from rcm_kin.statics.maps import MAX_POSES

EPILOG_VIEW = ("examples: rcm-kin view psm --q 10 -5 0.08 --deg --html psm.html   (self-contained page)\n"
               "          rcm-kin view my_arm.toml --package-dir my_arm_description=./meshes_pkg --html arm.html\n"
               "          rcm-kin view mtm --frames wrist_center tool_tip   (serves on localhost, prints the URL)\n"
               "          rcm-kin view psm --q 10 -5 0.08 --deg --png psm.png   (matplotlib drawing)\n"
               "          rcm-kin view psm --q 10 -5 0.08 --deg --png psm.png --renderer browser   (Chromium)")
EPILOG_REPORT = ("examples: rcm-kin report --out report   (then open report/index.html)\n"
                 "          rcm-kin report --out report --data ../shared/data   (with the measured logs)")


def add_view(sub) -> None:
    p = sub.add_parser("view", help="meshcat view of a robot: served on localhost, or a self-contained HTML page",
                       parents=[any_robot()], epilog=EPILOG_VIEW, formatter_class=RAW)
    p.add_argument("--q", nargs="*", default=[], metavar="Q",
                   help="actuated joint values in 'info' order (rad, m; missing trailing values are 0)")
    p.add_argument("--deg", action="store_true", help="revolute values in degrees (prismatic stay in m)")
    p.add_argument("--frames", nargs="*", metavar="FRAME", help="frames to show as axis triads (e.g. rcm tool_tip)")
    p.add_argument("--html", metavar="FILE.html", help="write a self-contained page instead of serving")
    p.add_argument("--png", metavar="FILE.png", help="write a picture instead of serving (see --renderer)")
    p.add_argument("--renderer", choices=("matplotlib", "browser"), default="matplotlib",
                   help="--png: a matplotlib drawing (default), or the meshcat page as headless Chromium draws it")
    add_package_dirs(p)
    add_force(p)
    add_json(p, '{"robot", "q", "written": [files]} (with --html or --png)')
    p.set_defaults(func=cmd_view)


def add_report(sub) -> None:
    p = sub.add_parser("report", help="run the main job on the bundled models and write index.html",
                       epilog=EPILOG_REPORT)
    p.add_argument("--out", required=True, type=path_text, help="output folder (created)")
    p.add_argument("--force", action="store_true", help=FOLDER_FORCE)
    p.add_argument("--data", type=path_text,
                   help="folder of measured logs (psm-sysid layout): adds calibration, identification "
                        "per pose and the grey-box fit, and uses its MTM recording for target following")
    p.add_argument("--map-points", type=count(2, int(MAX_POSES**0.5)), default=61,
                   help=f"poses per axis of the holding-effort maps over +-30 deg (2 to {int(MAX_POSES**0.5)}, "
                        "default 61)")
    add_json(p, '{"index", "files": [paths relative to --out]}')
    p.set_defaults(func=cmd_report)


def cmd_view(args) -> None:
    """Files with ``--png``/``--html``; otherwise a live meshcat server until Ctrl-C (or SIGTERM)."""
    from rcm_kin.visualization.views import robot_view, show, write_html

    robot = load_robot(args.robot)
    q = joint_values(robot, args)
    frames = tuple(args.frames or ())
    packages = package_dirs(args)
    if args.renderer != "matplotlib" and args.png is None:
        raise RcmKinError(f"--renderer {args.renderer} draws the --png picture: give --png FILE.png")
    png = None if args.png is None else new_output(args.png, args.force, (".png",))
    page = None if args.html is None else new_output(args.html, args.force, (".html", ".htm"))
    if png or page:                   # meshes and frames found (or one error line) before any file is written
        viz = robot_view(robot, frames=frames, package_dirs=packages)
        show(viz, robot, q)
    written = []
    if png and args.renderer == "browser":
        from rcm_kin.visualization.browser import browser_png

        written.append(str(browser_png(robot, q, png, frames, package_dirs=packages)))
    elif png:
        from rcm_kin.visualization.drawing import robot_drawing

        written.append(str(robot_drawing(robot, q, png, title=robot.name.upper(), package_dirs=packages)))
    if page:
        written.append(str(write_html(viz, page)))
    if written:
        emit(args, {"robot": robot.name, "q": q.tolist(), "written": written},
             "\n".join(f"wrote {f}" for f in written))
        return
    _serve(robot, q, frames, packages)


def _serve(robot, q, frames: tuple[str, ...], packages=None) -> None:
    """A live meshcat server showing ``robot`` at ``q`` until Ctrl-C or SIGTERM; the server process
    is stopped either way."""
    import signal
    import time

    import meshcat

    from rcm_kin.visualization.views import robot_view, show

    def stop(signum, frame):
        raise KeyboardInterrupt

    live = meshcat.Visualizer()            # starts the meshcat server and prints its URL
    previous = signal.signal(signal.SIGTERM, stop)
    try:
        viz = robot_view(robot, window=live.window, frames=frames, package_dirs=packages)
        show(viz, robot, q)
        print("serving; press Ctrl-C to stop", flush=True)
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("stopped")
    finally:
        if live.window.server_proc is not None:
            live.window.server_proc.kill()
            live.window.server_proc.wait()
        signal.signal(signal.SIGTERM, previous)


def cmd_report(args) -> None:
    from rcm_kin.report import write_report

    index = write_report(new_folder(args.out, args.force), args.data, args.map_points, progress=progress_wanted(args))
    files = sorted(str(f.relative_to(index.parent)) for f in Path(index.parent).rglob("*")
                   if f.is_file() and not f.name.startswith(MANIFEST))
    emit(args, {"index": str(index), "files": files}, f"report written: {index} ({len(files)} files)")
