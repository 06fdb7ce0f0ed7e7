"""Video files from RGB frames: ``.gif`` (Pillow) or ``.mp4`` (imageio + ffmpeg), streamed.

``.gif`` is written with Pillow (always available: matplotlib depends on it); GIF stores
frame durations in 10 ms units, so 30 fps plays at 1000/30 ms rounded. ``.mp4`` needs
``imageio`` with its ffmpeg plugin (``pip install imageio[ffmpeg]``); without it a
`RenderError` says so.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.validation import check_positive
from geosyn.sim.errors import RenderError

#: Video formats, by file suffix.
FORMATS = (".gif", ".mp4")


def check_video_path(path: str | os.PathLike[str]) -> Path:
    """The path of a video file, once its format is known to be writable.

    Args:
        path: output file; its suffix (``.gif`` or ``.mp4``) picks the format.

    Raises:
        InvalidArgument: an unknown suffix.
        RenderError: ``.mp4`` but imageio/ffmpeg are not installed.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise InvalidArgument(f"path {str(path)!r} must end in one of {', '.join(FORMATS)}")
    if suffix == ".mp4":
        _mp4_writer()
    return path


def _mp4_writer() -> Any:
    """The ``imageio.v2`` module (with ffmpeg), or a `RenderError` saying how to get it."""
    try:  # deferred: imageio is the optional 'video' extra
        import imageio.v2 as iio
        import imageio_ffmpeg  # noqa: F401
    except ImportError as err:
        raise RenderError(
            "writing .mp4 needs imageio with ffmpeg (pip install 'imageio[ffmpeg]');"
            " use a .gif path instead"
        ) from err
    return iio


def write_frames(
    frames: Iterable[np.ndarray], path: str | os.PathLike[str], fps: float = 30.0
) -> Path:
    """Write RGB frames to a ``.gif`` (Pillow) or ``.mp4`` (imageio + ffmpeg), streaming.

    GIF frames are palette-quantized one by one as they arrive (adaptive 256 colours), so
    only the quantized images are held in memory; mp4 frames go straight to the encoder.

    Args:
        frames: (H, W, 3) uint8 RGB frames, all of one size (an array (F, H, W, 3) works).
        path: output file; its suffix picks the format.
        fps: frames per second [Hz], > 0.

    Returns:
        The path written.

    Raises:
        InvalidArgument: an unknown suffix, no frames, or a frame of the wrong type or size.
        RenderError: mp4 requested but imageio/ffmpeg are not installed, or writing failed.
    """
    path = check_video_path(path)
    fps = check_positive(fps, "fps", "Hz")
    shape: tuple[int, ...] | None = None

    def checked(f: np.ndarray, i: int) -> np.ndarray:
        nonlocal shape
        f = np.asarray(f)
        if f.ndim != 3 or f.shape[-1] != 3 or f.dtype != np.uint8 or (shape and f.shape != shape):
            raise InvalidArgument(
                f"frame {i} must be a (H, W, 3) uint8 array like frame 0 {shape},"
                f" got {f.shape} {f.dtype}"
            )
        shape = f.shape
        return f

    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".gif":
        from PIL import Image  # deferred: Pillow (via Matplotlib) only for a GIF

        images = [
            Image.fromarray(checked(f, i)).convert("P", palette=Image.Palette.ADAPTIVE, colors=256)
            for i, f in enumerate(frames)
        ]
        if not images:
            raise InvalidArgument("frames is empty; nothing to write")
        images[0].save(
            path,
            save_all=True,
            append_images=images[1:],
            duration=max(int(round(1000.0 / fps)), 10),
            loop=0,
            optimize=False,
        )
        return path
    imageio = _mp4_writer()
    count = 0
    try:
        with imageio.get_writer(path, fps=fps, macro_block_size=1) as writer:
            for i, f in enumerate(frames):
                writer.append_data(checked(f, i))
                count += 1
    except (InvalidArgument, RenderError):
        raise
    except Exception as err:  # the plugins raise their own types
        raise RenderError(f"could not write {str(path)!r}: {err}") from err
    if count == 0:
        raise InvalidArgument("frames is empty; nothing to write")
    return path


__all__ = ["FORMATS", "check_video_path", "write_frames"]
