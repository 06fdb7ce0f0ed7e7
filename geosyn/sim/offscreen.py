"""Offscreen RGB rendering of a MuJoCo model, with the OpenGL backend chosen at render time.

MuJoCo's Python package reads ``MUJOCO_GL`` once, when ``mujoco`` is first imported, and
``mujoco.Renderer`` always uses the backend chosen then (GLFW when unset, which needs a
display). geosyn neither sets ``MUJOCO_GL`` nor patches mujoco: `OffscreenRenderer`
creates its own OpenGL context, from the backend `gl_backend` names when it is built:

- ``MUJOCO_GL`` set (``egl``, ``osmesa``, ``glfw``, ``cgl``): that backend;
- unset, on Linux: ``egl`` (headless, with or without a display);
- unset, elsewhere: the platform's default (MuJoCo's own choice).

MuJoCo's EGL and OSMesa modules set ``PYOPENGL_PLATFORM`` when first imported (PyOpenGL
binds its platform then, for the process); the variable is restored afterwards, so the
environment a caller sees, and passes to child processes, is the one it set.
"""

from __future__ import annotations

import importlib
import os
import platform
from collections.abc import Sequence
from types import TracebackType
from typing import Any, NamedTuple

import mujoco
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.sim.errors import RenderError

#: Backends by ``MUJOCO_GL`` value, and the mujoco module holding each one's GLContext.
_BACKENDS = {
    "egl": "mujoco.egl",
    "osmesa": "mujoco.osmesa",
    "glfw": "mujoco.glfw",
    "cgl": "mujoco.cgl",
}
_UNSET = ("", "enable", "enabled", "on", "true", "1")
_HINT = "on a headless Linux machine set MUJOCO_GL=egl (GPU) or MUJOCO_GL=osmesa (software)"


def gl_backend() -> str:
    """The OpenGL backend a renderer built now uses.

    Returns:
        ``MUJOCO_GL`` (lower case) when set, else ``"egl"`` on Linux, else ``"default"``
        (the platform's backend as chosen by mujoco at import).
    """
    requested = os.environ.get("MUJOCO_GL", "").lower().strip()
    if requested in _UNSET:
        return "egl" if platform.system() == "Linux" else "default"
    return requested


def _context_class(backend: str) -> Any:
    """The GLContext class of a backend (imported now), or a `RenderError`."""
    if backend == "default":
        cls = getattr(mujoco, "GLContext", None)
        if cls is None:
            raise RenderError(f"mujoco has no OpenGL backend on this platform; {_HINT}")
        return cls
    module = _BACKENDS.get(backend)
    if module is None:
        raise RenderError(
            f"MUJOCO_GL={backend!r} names no backend geosyn can render with; use one of"
            f" {', '.join(_BACKENDS)}"
        )
    saved = os.environ.get("PYOPENGL_PLATFORM")
    try:
        return importlib.import_module(module).GLContext
    except (ImportError, AttributeError, OSError) as err:
        raise RenderError(
            f"the OpenGL backend {backend!r} (MUJOCO_GL={os.environ.get('MUJOCO_GL')!r}) could"
            f" not be loaded: {err}; {_HINT}"
        ) from err
    finally:
        if saved is None:
            os.environ.pop("PYOPENGL_PLATFORM", None)
        else:
            os.environ["PYOPENGL_PLATFORM"] = saved


class Overlay(NamedTuple):
    """Texts drawn over an image.

    Attributes:
        text: lines shown top left, white on a dark box.
        legend: (text, (r, g, b) in 0..1) entries shown bottom left, each in its colour.
    """

    text: str = ""
    legend: Sequence[tuple[str, tuple[float, float, float]]] = ()


class OffscreenRenderer:
    """RGB images of a model's scene from an OpenGL context it owns.

    Use as a context manager (or call `close`) to free the context. Building allocates
    the context, MuJoCo's render context and a (height, width, 3) pixel buffer.

    Args:
        model: the model drawn.
        width: image width [px], at most the model's offscreen buffer width.
        height: image height [px], at most its offscreen buffer height.
        max_geom: capacity of the visual scene (geoms and added markers).

    Attributes:
        backend: the OpenGL backend used (see `gl_backend`).
        scene: the `mujoco.MjvScene` drawn; `update` fills it, markers may be appended.

    Raises:
        InvalidArgument: the size exceeds the model's offscreen buffer.
        RenderError: no OpenGL context could be made; the message names the backend and
            ``MUJOCO_GL``.
    """

    def __init__(
        self, model: mujoco.MjModel, width: int, height: int, max_geom: int = 4000
    ) -> None:
        offwidth, offheight = model.vis.global_.offwidth, model.vis.global_.offheight
        if not (0 < width <= offwidth and 0 < height <= offheight):
            raise InvalidArgument(
                f"width x height must be within the model's offscreen buffer"
                f" {offwidth} x {offheight} [px], got {width} x {height}"
            )
        self.model = model
        self.backend = gl_backend()
        self._gl: Any = None
        self._ctx: Any = None
        cls = _context_class(self.backend)
        try:
            self._gl = cls(width, height)
            self._gl.make_current()
            self._ctx = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150.value)
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, self._ctx)
        except Exception as err:  # backends raise ImportError/RuntimeError/FatalError/...
            self.close()
            raise RenderError(
                f"could not create an OpenGL context with backend {self.backend!r}"
                f" (MUJOCO_GL={os.environ.get('MUJOCO_GL')!r}): {err}; {_HINT}"
            ) from err
        self.scene = mujoco.MjvScene(model, maxgeom=max_geom)
        self._option = mujoco.MjvOption()
        self._rect = mujoco.MjrRect(0, 0, width, height)
        self._rgb = np.empty((height, width, 3), dtype=np.uint8)

    def update(
        self,
        data: mujoco.MjData,
        camera: mujoco.MjvCamera,
        option: mujoco.MjvOption | None = None,
    ) -> None:
        """Fill `scene` with the model's geoms at the state of ``data``.

        Args:
            data: MuJoCo data of ``model`` with its kinematics computed (``mj_forward``).
            camera: the camera the scene is seen from.
            option: visibility options (geom groups, ...); MuJoCo's defaults when None.
        """
        mujoco.mjv_updateScene(
            self.model,
            data,
            self._option if option is None else option,
            None,
            camera,
            mujoco.mjtCatBit.mjCAT_ALL.value,
            self.scene,
        )

    def render(self, overlay: Overlay | None = None) -> np.ndarray:
        """Draw `scene`, then the texts of ``overlay``.

        Args:
            overlay: texts to draw over the image (none by default).

        Returns:
            (height, width, 3) uint8 RGB image, top row first (a fresh array).
        """
        if self._ctx is None:
            raise RenderError("render() called after close()")
        self._gl.make_current()
        mujoco.mjr_render(self._rect, self.scene, self._ctx)
        if overlay is not None:
            self._draw(overlay)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._ctx)
        return np.flipud(self._rgb).copy()  # OpenGL's first row is the bottom one

    def _draw(self, overlay: Overlay) -> None:
        font = mujoco.mjtFont.mjFONT_NORMAL
        # Legend first: mjr_text places text relative to the current viewport, which
        # mjr_overlay shrinks to its box. Entries from the bottom up, ~20 px per line.
        step = min(0.1, 20.0 / max(self._rect.height, 1))
        for i, (text, rgb) in enumerate(reversed(list(overlay.legend))):
            mujoco.mjr_text(font, text, self._ctx, 0.02, 0.03 + i * step, *rgb)
        if overlay.text:
            grid = mujoco.mjtGridPos.mjGRID_TOPLEFT
            mujoco.mjr_overlay(font, grid, self._rect, overlay.text, "", self._ctx)

    def close(self) -> None:
        """Free MuJoCo's render context and the OpenGL context (idempotent)."""
        if self._ctx is not None:
            self._gl.make_current()  # MuJoCo frees its GL objects in the current context
            self._ctx.free()
            self._ctx = None
        if self._gl is not None:
            self._gl.free()
            self._gl = None

    def __enter__(self) -> OffscreenRenderer:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


__all__ = ["OffscreenRenderer", "Overlay", "gl_backend"]
