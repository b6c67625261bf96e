"""A view drawn under one root frame of the scene, shown or hidden as a whole."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import viser


class Rooted:
    """Mixin: `visible` shows or hides the view's `root` frame, and so everything under it."""

    root: viser.FrameHandle

    @property
    def visible(self) -> bool:
        return self.root.visible

    @visible.setter
    def visible(self, shown: bool) -> None:
        self.root.visible = shown
