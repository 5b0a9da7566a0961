"""Meshcat without a server: record a scene in-process and render it as one self-contained HTML file.

`RecordingWindow` stands in for meshcat-python's `ViewerWindow` (no zmq server, no port): it keeps the
scene tree the server would keep and renders the static HTML the way the server's `get_scene` does,
except that animations go last, and with an optional overlay (HTML put over the 3D view, e.g. a legend).
`text_and_plane_classes` gives two element types the Meshcat viewer draws but meshcat-python 0.3.2 lacks;
`mesh_in_order` a mesh with a three.js ``renderOrder`` (drawn after the scene: markers that stay visible).
meshcat is imported lazily, inside the functions.

    >>> window = RecordingWindow()
    >>> vis = import_meshcat().Visualizer(window=window)
    >>> ...  # vis[path].set_object(...), set_transform, set_animation
    >>> window.overlay = "<div>legend</div>"   # optional
    >>> html = vis.static_html()
"""

from __future__ import annotations

import base64
import warnings
from pathlib import Path

__all__ = ["RecordingWindow", "HTML_TEMPLATE", "import_meshcat", "mesh_in_order", "text_and_plane_classes"]


class RecordingWindow:
    """Stands in for meshcat's ViewerWindow: keeps the scene tree in-process and renders static HTML the
    way meshcat's server does for `get_scene` (no server, no port)."""

    def __init__(self) -> None:
        import_meshcat()
        from meshcat.servers.tree import SceneTree

        self.tree = SceneTree()
        self.web_url = ""
        self.overlay = ""
        """HTML put after the viewer's scripts (over the 3D view), e.g. `replay_overlay.overlay_html`."""

    def send(self, command) -> None:
        import umsgpack
        from meshcat.servers.tree import find_node

        data = command.lower()
        packed = umsgpack.packb(data, force_float_precision="single")
        path = [p for p in data["path"].split("/") if p]
        node = find_node(self.tree, path)
        kind = data["type"]
        if kind == "set_object":
            node.object, node.properties = packed, []
        elif kind == "set_transform":
            node.transform = packed
        elif kind == "set_property":
            node.properties.append(packed)
        elif kind == "set_animation":
            node.animation = packed
        else:  # pragma: no cover - not used by this module
            raise ValueError(f"unsupported meshcat command {kind}")

    def get_scene(self) -> str:
        from meshcat.servers.tree import walk

        def cmd(data: bytes) -> str:
            return ('\nfetch("data:application/octet-binary;base64,{}")\n.then(res => res.arrayBuffer())\n'
                    '.then(buffer => viewer.handle_command_bytearray(new Uint8Array(buffer)));\n'
                    ).format(base64.b64encode(data).decode("utf-8"))

        # Unlike meshcat's server, the animation goes LAST: three.js records each animated property's
        # value when the animation starts and afterwards writes a property only when its animated value
        # changes, so a static value set after the start would stay on screen until then.
        commands, animations = [], []
        for node in walk(self.tree):
            if node.object is not None:
                commands.append(cmd(node.object))
            commands.extend(cmd(p) for p in node.properties)
            if node.transform is not None:
                commands.append(cmd(node.transform))
            if node.animation is not None:
                animations.append(cmd(node.animation))
        commands += animations
        import meshcat

        js = (Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js").read_text(encoding="utf-8")
        return HTML_TEMPLATE.format(mainminjs=js, commands="".join(commands), overlay=self.overlay)


HTML_TEMPLATE = """<!DOCTYPE html>
<html>
<head> <meta charset=utf-8> <title>MeshCat</title> </head>
<body>
<div id="meshcat-pane"></div>
<script>
{mainminjs}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
{commands}
</script>
<style> body {{margin: 0; }} #meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }} </style>
<script id="embedded-json"></script>
{overlay}
</body>
</html>
"""


def import_meshcat():
    """Import meshcat (lazily), silencing the deprecation warning its zmq server module raises."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import meshcat
        import meshcat.animation  # noqa: F401
        import meshcat.geometry  # noqa: F401
        import meshcat.servers.tree  # noqa: F401
    return meshcat


def text_and_plane_classes():
    """Two Meshcat element types missing from meshcat-python 0.3.2 but drawn by its viewer: a text canvas
    texture (`_text`) and a plane geometry."""
    import meshcat.geometry as g

    class TextTexture(g.Texture):
        def __init__(self, text: str, font_size: int = 48, font_face: str = "sans-serif"):
            super().__init__()
            self.text, self.font_size, self.font_face = text, font_size, font_face

        def lower(self, object_data):
            return {"uuid": self.uuid, "type": "_text", "text": self.text,
                    "font_size": self.font_size, "font_face": self.font_face}

    class Plane(g.Geometry):
        def __init__(self, width: float, height: float):
            super().__init__()
            self.width, self.height = width, height

        def lower(self, object_data):
            return {"uuid": self.uuid, "type": "PlaneGeometry", "width": self.width, "height": self.height,
                    "widthSegments": 1, "heightSegments": 1}

    return TextTexture, Plane


def mesh_in_order(geometry, material, render_order: int):
    """A Meshcat mesh drawn in three.js ``renderOrder`` `render_order` (objects of a higher order are drawn
    later; with a material that does not depth-test, over everything drawn before). For a transparent
    material (three.js draws transparent objects after the opaque ones) that is over the whole scene."""
    import meshcat.geometry as g

    class OrderedMesh(g.Mesh):
        def lower(self):
            data = super().lower()
            data["object"]["renderOrder"] = int(render_order)
            return data

    return OrderedMesh(geometry, material)
