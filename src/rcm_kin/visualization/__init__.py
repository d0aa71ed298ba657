"""meshcat views of the robots: served live, or written as self-contained HTML pages."""

import lazy_loader

__all__ = ["OfflineWindow", "SideCamera", "animate", "browser_png", "robot_drawing", "robot_view", "set_camera",
           "show", "side_camera", "write_html"]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "views": ["robot_view", "show", "animate", "write_html"],
        "offline": ["OfflineWindow"],
        "drawing": ["robot_drawing"],
        "browser": ["browser_png"],
        "camera": ["SideCamera", "side_camera", "set_camera"],
    },
)
