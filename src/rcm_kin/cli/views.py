"""``view`` and ``report``: a robot in meshcat or matplotlib, and the HTML report of the main job."""

from __future__ import annotations

from rcm_kin.cli.common import RAW, any_robot, joint_values
from rcm_kin.robot import load_robot

EPILOG_VIEW = ("examples: rcm-kin view psm --q 10 -5 0.08 --deg --html psm.html   (self-contained page)\n"
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
    p.add_argument("--html", metavar="FILE", help="write a self-contained page instead of serving")
    p.add_argument("--png", metavar="FILE", help="write a picture instead of serving (see --renderer)")
    p.add_argument("--renderer", choices=("matplotlib", "browser"), default="matplotlib",
                   help="--png: a matplotlib drawing (default), or the meshcat page as headless Chromium draws it")
    p.set_defaults(func=cmd_view)


def add_report(sub) -> None:
    p = sub.add_parser("report", help="run the main job on the bundled models and write index.html",
                       epilog=EPILOG_REPORT)
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--data", help="folder of measured logs (psm-sysid layout): adds calibration, identification "
                                  "per pose and the grey-box fit, and uses its MTM recording for target following")
    p.add_argument("--map-points", type=int, default=61,
                   help="poses per axis of the holding-effort maps over +-30 deg (default 61)")
    p.set_defaults(func=cmd_report)


def cmd_view(args) -> None:
    """Files with ``--png``/``--html``; otherwise a live meshcat server until Ctrl-C."""
    from rcm_kin.visualization.views import robot_view, show, write_html

    robot = load_robot(args.robot)
    q = joint_values(robot, args)
    frames = tuple(args.frames or ())
    if args.png and args.renderer == "browser":
        from rcm_kin.visualization.browser import browser_png

        print(f"wrote {browser_png(robot, q, args.png, frames)}")
    elif args.png:
        from rcm_kin.visualization.drawing import robot_drawing

        print(f"wrote {robot_drawing(robot, q, args.png, title=robot.name.upper())}")
    if args.html:
        viz = robot_view(robot, frames=frames)
        show(viz, robot, q)
        print(f"wrote {write_html(viz, args.html)}")
    if args.html or args.png:
        return
    import meshcat

    live = meshcat.Visualizer()            # starts the meshcat server and prints its URL
    viz = robot_view(robot, window=live.window, frames=frames)
    show(viz, robot, q)
    print("serving; press Ctrl-C to stop", flush=True)
    try:
        import time
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("stopped")


def cmd_report(args) -> None:
    from rcm_kin.report import write_report

    index = write_report(args.out, args.data, args.map_points, progress=True)
    print(f"report written: {index}")
