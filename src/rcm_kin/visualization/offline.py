"""A meshcat window without a server: it keeps the scene as the meshcat server does and writes
it as one self-contained HTML page (the viewer's JavaScript inlined, no network sources).

``meshcat.Visualizer(window=OfflineWindow())`` takes every meshcat and Pinocchio-visualizer
call; :meth:`OfflineWindow.get_scene` returns the page (what ``Visualizer.static_html()``
asks the server for). A ``set_target`` command (the point the camera's orbit controls look at,
which the viewer of meshcat 0.3.2 cannot take as a command) is kept and set by the page after
the scene is replayed.
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path

import meshcat
import msgpack
import umsgpack
from meshcat.servers.tree import SceneTree, find_node, walk

VIEWER_JS = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"


def _ext(value):
    """meshcat's packed arrays (``umsgpack.Ext``) as msgpack's extension type."""
    if isinstance(value, umsgpack.Ext):
        return msgpack.ExtType(value.type, value.data)
    raise TypeError(f"cannot pack {type(value).__name__}")


def pack(command: dict) -> bytes:
    """A lowered meshcat command as msgpack bytes: the bytes meshcat's ``umsgpack.packb`` writes
    (a declared twin, ``tests/visualization/test_views.py``), by msgpack's C packer, about ten
    times faster (an animation's keyframes are some 16 000 maps)."""
    return msgpack.packb(command, use_bin_type=True, default=_ext)


class OfflineWindow:
    """Records meshcat commands into a scene tree (last object, transform and animation per path)."""

    web_url = "(offline: write the page with static_html())"

    def __init__(self, title: str = "rcm-kin"):
        self.tree = SceneTree()
        self.title = title
        self.camera_target: list[float] | None = None     # camera frame (y up), m

    def send(self, command) -> None:
        """Keep ``command`` as the meshcat server would (a property replaces its earlier value)."""
        data = command.lower()
        if data["type"] == "set_target":
            self.camera_target = [float(v) for v in data["value"]]
            return
        path = [p for p in data["path"].split("/") if p]
        packed = pack(data)
        kind = data["type"]
        if kind == "delete":
            if path:
                parent = find_node(self.tree, path[:-1])
                if path[-1] in parent:
                    del parent[path[-1]]
            else:
                self.tree = SceneTree()
            return
        node = find_node(self.tree, path)
        if kind == "set_object":
            node.object, node.properties = packed, []
        elif kind == "set_transform":
            node.transform = packed
        elif kind == "set_property":
            node.properties = [p for p in node.properties if msgpack.unpackb(p)["property"] != data["property"]]
            node.properties.append(packed)
        elif kind == "set_animation":
            node.animation = packed

    def get_scene(self) -> str:
        """The scene as one self-contained HTML page."""
        commands = []
        for node in walk(self.tree):
            blobs = [node.object, *node.properties, node.transform, node.animation]
            commands += [base64.b64encode(b).decode("ascii") for b in blobs if b is not None]
        calls = "\n".join(f'load("{c}");' for c in commands)
        if self.camera_target is not None:
            calls += (f"\nviewer.controls.target.set(...{json.dumps(self.camera_target)});"
                      "\nviewer.controls.update();\nviewer.set_dirty();")
        return (f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>{html.escape(self.title)}</title>"
                "<style>body{margin:0}#meshcat-pane{width:100vw;height:100vh;overflow:hidden}</style></head>"
                f"<body><div id='meshcat-pane'></div><script>{VIEWER_JS.read_text()}</script><script>\n"
                "var viewer = new MeshCat.Viewer(document.getElementById('meshcat-pane'));\n"
                "function load(b64) { var s = atob(b64), a = new Uint8Array(s.length);\n"
                "  for (var i = 0; i < s.length; i++) a[i] = s.charCodeAt(i);\n"
                "  viewer.handle_command_bytearray(a); }\n"
                f"{calls}\n</script></body></html>\n")

    def get_image(self):                 # the Pinocchio visualizer checks that it exists
        raise NotImplementedError("an offline window renders nothing itself: open the HTML page")

    def close(self) -> None:
        pass
