"""Perception of a coloured ball in RGB-D images: segmentation, back-projection, fit.

A pinhole camera (`PinholeCamera`: pose and focal length in pixels) sees an image whose
pixels of the target's colour (`colour_mask`, by chromaticity, so shading does not
matter) are back-projected with their depth to points on the ball's visible surface
(`back_project`); the ball's centre is the least-squares fit of a sphere of known radius
to those points (`fit_sphere`, Gauss-Newton), with its covariance from the residuals.
Pure numpy: the images may come from `geosyn.sim.camera_sensor` (MuJoCo, offscreen) or a
real camera.

Camera axes (world frame): ``forward`` along the optical axis, ``up`` the image's up,
``right = forward x up``. Pixel (row i, column j), top row first, has the ray
``forward + x right + y up`` with ``x = (j + 1/2 - W/2) / f`` and ``y = -(i + 1/2 - H/2) / f``;
depth is the distance along ``forward`` [m].
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Matrix, Vector
from geosyn.core.validation import check_positive, check_vec3


class PinholeCamera(NamedTuple):
    """A pinhole camera with square pixels and the principal point at the image centre.

    Attributes:
        position: (3,) optical centre in the world [m].
        forward: (3,) unit optical axis in the world.
        up: (3,) unit image up direction in the world (orthogonal to ``forward``).
        focal: focal length [px].
        width: image width [px].
        height: image height [px].
    """

    position: Vector
    forward: Vector
    up: Vector
    focal: float
    width: int
    height: int

    @property
    def right(self) -> Vector:
        """(3,) unit image right direction in the world."""
        return np.cross(self.forward, self.up)

    def project(self, points: Matrix) -> Matrix:
        """(N, 3) world points [m] -> (N, 3) (row, column [px], depth [m])."""
        d = np.atleast_2d(points) - self.position
        z = d @ self.forward
        x, y = d @ self.right / z, d @ self.up / z
        col = x * self.focal + self.width / 2 - 0.5
        row = -y * self.focal + self.height / 2 - 0.5
        return np.stack([row, col, z], axis=1)


class TargetEstimate(NamedTuple):
    """A ball's estimated centre.

    Attributes:
        position: (3,) centre in the world [m].
        covariance: (3, 3) covariance of ``position`` [m^2] (residual variance times
            the inverse Gauss-Newton normal matrix).
        pixels: number of target pixels used.
        rms: root-mean-square distance of the points from the fitted sphere [m].
    """

    position: Vector
    covariance: Matrix
    pixels: int
    rms: float

    @property
    def std(self) -> Vector:
        """(3,) standard deviations of the position [m]."""
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))


def colour_mask(
    rgb: np.ndarray, colour: Sequence[float] | np.ndarray, tol: float = 0.08, min_value: int = 30
) -> np.ndarray:
    """Pixels whose chromaticity ``rgb / (r + g + b)`` is within ``tol`` of ``colour``'s.

    Args:
        rgb: (H, W, 3) uint8 image.
        colour: (3,) target colour (any positive scale, e.g. an rgba's first three).
        tol: largest max-norm chromaticity difference [-].
        min_value: darker pixels (max channel below this) are ignored.

    Returns:
        (H, W) bool mask.
    """
    img = np.asarray(rgb)
    if img.ndim != 3 or img.shape[2] != 3:
        raise InvalidArgument(f"rgb must be an (H, W, 3) image, got shape {img.shape}")
    c = np.asarray(colour, dtype=np.float64)[:3]
    c = c / c.sum()
    f = img.astype(np.float32)
    s = f.sum(axis=2) + 1e-6
    chroma = f / s[..., None]
    close = np.max(np.abs(chroma - c.astype(np.float32)), axis=2) <= tol
    return close & (img.max(axis=2) >= min_value)


def erode(mask: np.ndarray) -> np.ndarray:
    """The mask without its border pixels (4-neighbourhood): silhouette pixels mix the
    ball's depth with the background's and are dropped."""
    m = np.asarray(mask, dtype=bool)
    out = m.copy()
    out[1:, :] &= m[:-1, :]
    out[:-1, :] &= m[1:, :]
    out[:, 1:] &= m[:, :-1]
    out[:, :-1] &= m[:, 1:]
    out[0, :] = out[-1, :] = False
    out[:, 0] = out[:, -1] = False
    return out


def back_project(camera: PinholeCamera, depth: np.ndarray, mask: np.ndarray) -> Matrix:
    """World points of the masked pixels.

    Args:
        camera: the camera.
        depth: (H, W) depth along the optical axis [m].
        mask: (H, W) bool, the pixels to back-project.

    Returns:
        (N, 3) points in the world [m].
    """
    rows, cols = np.nonzero(mask)
    return pixel_points(camera, depth, rows, cols)


def pixel_points(
    camera: PinholeCamera, depth: np.ndarray, rows: np.ndarray, cols: np.ndarray
) -> Matrix:
    """(N, 3) world points [m] of pixels (N,) rows and (N,) columns, with their depth."""
    z = np.asarray(depth, dtype=np.float64)[rows, cols]
    x = (cols + 0.5 - camera.width / 2) / camera.focal
    y = -(rows + 0.5 - camera.height / 2) / camera.focal
    rays = (
        camera.forward[None, :]
        + x[:, None] * camera.right[None, :]
        + y[:, None] * camera.up[None, :]
    )
    return camera.position + z[:, None] * rays


def fit_sphere(
    points: Matrix, radius: float, toward: Vector, iterations: int = 10
) -> tuple[Vector, Matrix, float]:
    """Centre of the sphere of known radius best fitting surface points (Gauss-Newton).

    .. math:: \\min_c \\sum_i (\\|p_i - c\\| - r)^2

    started from the points' mean moved by ``r`` away from ``toward`` (the camera: the
    visible cap lies between it and the centre).

    Args:
        points: (N, 3) surface points [m], N >= 4.
        radius: sphere radius r [m], > 0.
        toward: (3,) the camera position [m].
        iterations: Gauss-Newton iterations.

    Returns:
        ((3,) centre [m], (3, 3) covariance [m^2], rms residual [m]).
    """
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 4:
        raise InvalidArgument(f"points must be (N, 3) with N >= 4, got shape {P.shape}")
    radius = check_positive(radius, "radius", "m")
    mean = P.mean(axis=0)
    away = mean - check_vec3(toward, "toward")
    c = mean + radius * away / np.linalg.norm(away)
    for _ in range(iterations):
        d = P - c
        dist = np.sqrt(np.einsum("ij,ij->i", d, d))
        J = -d / dist[:, None]
        step = np.linalg.solve(J.T @ J, -(J.T @ (dist - radius)))
        c = c + step
        if float(step @ step) < 1e-18:  # 1 nm
            break
    d = P - c
    dist = np.linalg.norm(d, axis=1)
    r = dist - radius
    J = -d / dist[:, None]
    dof = max(len(P) - 3, 1)
    sigma2 = float(r @ r) / dof
    cov = sigma2 * np.linalg.inv(J.T @ J)
    return c, cov, float(np.sqrt(np.mean(r * r)))


def estimate_ball(
    camera: PinholeCamera,
    rgb: np.ndarray,
    depth: np.ndarray,
    colour: Sequence[float] | np.ndarray,
    radius: float,
    *,
    tol: float = 0.08,
    min_pixels: int = 8,
    stride: int = 4,
) -> TargetEstimate | None:
    """The centre of a ball of ``colour`` and ``radius`` seen in an RGB-D image.

    Args:
        camera: the camera that took the image.
        rgb: (H, W, 3) uint8 image.
        depth: (H, W) depth along the optical axis [m].
        colour: (3,) the ball's colour.
        radius: the ball's radius [m].
        tol: chromaticity tolerance of `colour_mask`.
        min_pixels: fewer interior target pixels than this: None (not seen, e.g. occluded).
        stride: pixel step of the coarse search (the ball must span more than about
            ``stride`` pixels); one bounding box of all coarse hits is refined.

    Returns:
        The estimate, or None when the ball is not seen.
    """
    img = np.asarray(rgb)
    # coarse to fine: every `stride`-th pixel locates the ball, the full resolution is
    # segmented in its bounding box only (the cost of segmentation is per pixel)
    coarse = colour_mask(img[::stride, ::stride], colour, tol)
    rows, cols = np.nonzero(coarse)
    if rows.size == 0:
        return None
    pad = 2 * stride
    r0, r1 = max(rows.min() * stride - pad, 0), min(rows.max() * stride + pad + 1, img.shape[0])
    c0, c1 = max(cols.min() * stride - pad, 0), min(cols.max() * stride + pad + 1, img.shape[1])
    rows, cols = np.nonzero(erode(colour_mask(img[r0:r1, c0:c1], colour, tol)))
    n = int(rows.size)
    if n < max(min_pixels, 4):
        return None
    pts = pixel_points(camera, depth, rows + r0, cols + c0)
    c, cov, rms = fit_sphere(pts, radius, camera.position)
    return TargetEstimate(c, cov, n, rms)


__all__ = [
    "PinholeCamera",
    "TargetEstimate",
    "back_project",
    "colour_mask",
    "erode",
    "estimate_ball",
    "fit_sphere",
    "pixel_points",
]
