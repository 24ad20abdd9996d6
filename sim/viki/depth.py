"""LiDAR-camera depth fusion and object localisation of ViKi-HyCo, eq. 11-18 (section II-C, II-D).

Pure numpy (no PyBullet): this module turns LiDAR returns and a camera depth image into the
fused depth image, the object depth and the object position that the car controller needs.

Conventions
-----------
* Camera frame: OpenCV (x right, y down, z forward). Pixel ``(u, v)``: column ``u``, row ``v``,
  pixel centres at integer coordinates (OpenCV convention), so a projected point lands on pixel
  ``(rint(u), rint(v))``. Images are ``(height, width)`` arrays indexed ``[v, u]``; a depth of 0
  means "no data" (eq. 15 and 17 rely on it).
* LiDAR frame: x forward, y left, z up (Velodyne). ``T_camera_lidar = ^{c}T_l`` (4x4) maps LiDAR points to
  camera coordinates, as in eq. 11. Beam elevations are in radians, positive up; azimuths in
  radians about the LiDAR z axis, 0 along x, positive towards y (left).
* ``intrinsics`` is ``(fx, fy, cu, cv)`` in pixels or a 3x3 ``K``. The PyBullet TinyRenderer's
  principal point sits at ``(W/2, H/2 - 1)`` (SIMULATOR_NOTES.md, Vision); pass what the camera
  really has.

As-meant readings
-----------------
* Eq. 11-12 keep pixels ``0 < u < W``; we keep ``0 <= u < W`` (column 0 is a valid pixel) and
  drop points behind the camera. When several points fall on one pixel the nearest is kept.
* Eq. 12 prints ``||X_l + Y_l + Z_l||_2``; it means the Euclidean norm
  ``sqrt(X_l^2 + Y_l^2 + Z_l^2)`` of the LiDAR point (``value="range"``, the default). Note that
  eq. 18 and the interaction matrix use the depth as the camera ``Z`` and that a depth camera's
  image holds ``Z`` too; ``value="camera_z"`` gives that quantity (and ``"camera_range"`` the norm
  in the camera frame), which makes the fused image of eq. 15 consistent.
* Eq. 13 prints ``X^2 + Y^2 + Zhl = R^2``; meant is the set of ground points (``z = -h`` below
  the LiDAR) with ``X^2 + Y^2 <= R^2``, the LiDAR's blind disc. ``R = h / tan(|lowest beam|)``:
  1.10 m / tan(15 deg) = 4.1052 m, the paper's value. The paper samples that disc every 0.1 cm
  and projects the samples; we back-project every pixel to the ground instead (same set, no
  holes).
* Eq. 15 prints ``dfI = dI_l + M . dI_c``, which would add both depths where the LiDAR does see
  something inside the mask; we take the camera depth inside the mask where it is valid and the
  LiDAR depth everywhere else (identical to eq. 15 whenever ``dI_l`` is 0 inside the mask, the
  paper's premise).
* Eq. 17 prints the sum of the indicator ``[dI != 0]`` over ``n``; meant is the mean of the
  non-zero depths inside the shrunk box of eq. 16 (NaN and inf also count as "no data").
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "blind_spot_radius",
    "project_lidar_points",
    "interpolate_lidar_layers",
    "lidar_ranges_to_points",
    "blind_spot_mask",
    "fuse_depth",
    "shrunk_box",
    "object_depth",
    "object_position",
]

_VALUES = ("range", "camera_range", "camera_z")


def _intrinsics(intrinsics: ArrayLike) -> tuple[float, float, float, float]:
    a = np.asarray(intrinsics, dtype=float)
    if a.shape == (3, 3):
        fx, fy, cu, cv = a[0, 0], a[1, 1], a[0, 2], a[1, 2]
    elif a.shape == (4,):
        fx, fy, cu, cv = a
    else:
        raise ValueError(f"intrinsics must be (fx, fy, cu, cv) or a 3x3 K, got shape {a.shape}")
    if not (fx > 0.0 and fy > 0.0):
        raise ValueError(f"focal lengths must be positive, got fx={fx}, fy={fy}")
    return float(fx), float(fy), float(cu), float(cv)


def _transform(T: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    a = np.asarray(T, dtype=float)
    if a.shape not in ((4, 4), (3, 4)):
        raise ValueError(f"T_camera_lidar must be a 4x4 (or 3x4) homogeneous transform, got shape {a.shape}")
    return a[:3, :3], a[:3, 3]


def _image_size(width: int, height: int) -> tuple[int, int]:
    w, h = int(width), int(height)
    if w <= 0 or h <= 0 or w != width or h != height:
        raise ValueError(f"width and height must be positive integers, got {width}, {height}")
    return w, h


def blind_spot_radius(lidar_height: float = 1.10, lowest_beam: float = np.deg2rad(-15.0)) -> float:
    """Radius (m) of the ground disc the LiDAR cannot see: ``h / tan(|lowest beam|)``.

    Defaults are the paper's VLP-16 at 1.10 m: 4.1052 m (section II-C).
    """
    if not lidar_height > 0.0:
        raise ValueError(f"lidar_height must be positive, got {lidar_height}")
    if not (0.0 < abs(lowest_beam) < np.pi / 2):
        raise ValueError(f"lowest_beam must be a non-zero angle below 90 deg, got {lowest_beam}")
    return float(lidar_height / np.tan(abs(lowest_beam)))


def project_lidar_points(
    P_l: ArrayLike,
    T_camera_lidar: ArrayLike,
    intrinsics: ArrayLike,
    width: int,
    height: int,
    value: str = "range",
) -> NDArray[np.float64]:
    """Eq. 11-12: depth image ``dI_l`` (height x width) of LiDAR points ``P_l`` (N x 3).

    Each point is moved to the camera by ``T_camera_lidar``, projected with the pinhole model and written
    on pixel ``(rint(u), rint(v))`` if that pixel is in the image and the point is in front of
    the camera. ``value`` selects what is written (module docstring): ``"range"`` = norm of the
    LiDAR point (eq. 12 as meant), ``"camera_range"`` = norm in the camera frame, ``"camera_z"``
    = camera depth Z. The nearest point wins a pixel; pixels without a point are 0.
    """
    if value not in _VALUES:
        raise ValueError(f"value must be one of {_VALUES}, got {value!r}")
    w, h = _image_size(width, height)
    fx, fy, cu, cv = _intrinsics(intrinsics)
    R, t = _transform(T_camera_lidar)
    P = np.asarray(P_l, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3:
        raise ValueError(f"P_l must be an (N, 3) array, got shape {P.shape}")
    img = np.zeros((h, w))
    finite = np.all(np.isfinite(P), axis=1)
    P = P[finite]
    Pc = P @ R.T + t
    z = Pc[:, 2]
    front = z > 1e-9
    P, Pc, z = P[front], Pc[front], z[front]
    ui = np.rint(fx * Pc[:, 0] / z + cu)
    vi = np.rint(fy * Pc[:, 1] / z + cv)
    inside = (ui >= 0) & (ui < w) & (vi >= 0) & (vi < h)
    if not np.any(inside):
        return img
    if value == "range":
        val = np.linalg.norm(P[inside], axis=1)
    elif value == "camera_range":
        val = np.linalg.norm(Pc[inside], axis=1)
    else:
        val = z[inside]
    lin = vi[inside].astype(np.int64) * w + ui[inside].astype(np.int64)
    order = np.lexsort((val, lin))
    lin_s = lin[order]
    first = np.empty(lin_s.shape, dtype=bool)
    first[0] = True
    np.not_equal(lin_s[1:], lin_s[:-1], out=first[1:])
    img.flat[lin_s[first]] = val[order][first]
    return img


def _valid(r: NDArray[np.float64]) -> NDArray[np.bool_]:
    return np.isfinite(r) & (r > 0.0)


def interpolate_lidar_layers(
    ranges: ArrayLike, elevations: ArrayLike, n_virtual: int = 112
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Section II-C: densify a LiDAR range image from its beams to ``n_virtual`` layers.

    Parameters
    ----------
    ranges : (n_layers, n_azimuth)
        Range per beam and azimuth (m). No return: 0, NaN or inf.
    elevations : (n_layers,)
        Beam elevations (rad), any order, all distinct.
    n_virtual :
        Number of layers out (the paper: 16 -> 112), evenly spaced from the lowest to the highest
        beam elevation.

    Returns
    -------
    ``(ranges_v, elevations_v)``: ``(n_virtual, n_azimuth)`` ranges, linearly interpolated in
    elevation between the two adjacent beams of the same azimuth, and the ``(n_virtual,)``
    elevations (ascending). A virtual layer next to a no-return beam is a gap (0) unless it lies
    exactly on the other, valid beam: gaps are never bridged.
    """
    r = np.asarray(ranges, dtype=float)
    el = np.asarray(elevations, dtype=float)
    if r.ndim != 2 or el.shape != (r.shape[0],):
        raise ValueError(
            f"ranges must be (n_layers, n_az), one elevation per layer; got {r.shape}, {el.shape}"
        )
    if r.shape[0] < 2:
        raise ValueError("need at least two beams to interpolate")
    if int(n_virtual) != n_virtual or n_virtual < 2:
        raise ValueError(f"n_virtual must be an integer >= 2, got {n_virtual}")
    order = np.argsort(el)
    el = el[order]
    r = r[order]
    if np.any(np.diff(el) <= 0.0):
        raise ValueError("beam elevations must be distinct")
    ev = np.linspace(el[0], el[-1], int(n_virtual))
    i = np.clip(np.searchsorted(el, ev, side="right") - 1, 0, el.size - 2)
    s = ((ev - el[i]) / (el[i + 1] - el[i]))[:, None]
    s = np.clip(s, 0.0, 1.0)
    ok = _valid(r)
    lo, hi = r[i], r[i + 1]
    ok_lo, ok_hi = ok[i], ok[i + 1]
    eps = 1e-9
    out = np.zeros((ev.size, r.shape[1]))
    both = ok_lo & ok_hi
    with np.errstate(invalid="ignore"):
        mixed = (1.0 - s) * lo + s * hi
    np.copyto(out, mixed, where=both)
    at_lo = (s <= eps) & ok_lo & ~both
    at_hi = (s >= 1.0 - eps) & ok_hi & ~both
    np.copyto(out, np.broadcast_to(lo, out.shape), where=at_lo)
    np.copyto(out, np.broadcast_to(hi, out.shape), where=at_hi)
    return out, ev


def lidar_ranges_to_points(
    ranges: ArrayLike, elevations: ArrayLike, azimuths: ArrayLike
) -> NDArray[np.float64]:
    """Range image (n_layers x n_azimuth) back to LiDAR-frame points (N x 3), gaps dropped.

    ``p = r [cos(el) cos(az), cos(el) sin(az), sin(el)]``.
    """
    r = np.asarray(ranges, dtype=float)
    el = np.asarray(elevations, dtype=float)
    az = np.asarray(azimuths, dtype=float)
    if r.shape != (el.size, az.size):
        raise ValueError(f"ranges must be (len(elevations), len(azimuths)), got {r.shape}")
    ce, se = np.cos(el)[:, None], np.sin(el)[:, None]
    ca, sa = np.cos(az)[None, :], np.sin(az)[None, :]
    ok = _valid(r)
    pts = np.stack([r * ce * ca, r * ce * sa, r * se * np.ones_like(ca)], axis=-1)
    return pts[ok]


def blind_spot_mask(
    T_camera_lidar: ArrayLike,
    intrinsics: ArrayLike,
    width: int,
    height: int,
    lidar_height: float = 1.10,
    radius: float | None = None,
    lowest_beam: float = np.deg2rad(-15.0),
) -> NDArray[np.bool_]:
    """Eq. 13-14: mask ``M`` (height x width, bool) of pixels that see the LiDAR's blind disc.

    A pixel is in the mask when its viewing ray meets the ground plane (``z = -lidar_height`` in
    the LiDAR frame, LiDAR z up) in front of the camera at a point within ``radius`` of the
    LiDAR axis. ``radius`` defaults to :func:`blind_spot_radius` of ``lidar_height`` and
    ``lowest_beam`` (paper: 4.1052 m at 1.10 m). Computed once per camera mount (a preset in the
    paper's Fig. 1).
    """
    w, h = _image_size(width, height)
    fx, fy, cu, cv = _intrinsics(intrinsics)
    R, t = _transform(T_camera_lidar)
    if radius is None:
        radius = blind_spot_radius(lidar_height, lowest_beam)
    if not radius > 0.0:
        raise ValueError(f"radius must be positive, got {radius}")
    # Camera centre and pixel rays in the LiDAR frame: o = -R^T t, d = R^T K^-1 [u, v, 1].
    o = -R.T @ t
    x = ((np.arange(w) - cu) / fx)[None, :]
    y = ((np.arange(h) - cv) / fy)[:, None]
    dz = R[0, 2] * x + R[1, 2] * y + R[2, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (-lidar_height - o[2]) / dz
    hit = s > 0.0
    s = np.where(hit, s, 0.0)
    px = o[0] + s * (R[0, 0] * x + R[1, 0] * y + R[2, 0])
    py = o[1] + s * (R[0, 1] * x + R[1, 1] * y + R[2, 1])
    mask: NDArray[np.bool_] = hit & (px * px + py * py <= radius * radius)
    return mask


def fuse_depth(dI_l: ArrayLike, dI_c: ArrayLike, mask: ArrayLike) -> NDArray[np.float64]:
    """Eq. 15 as meant: camera depth inside the blind-spot mask (where valid), LiDAR elsewhere."""
    a = np.asarray(dI_l, dtype=float)
    b = np.asarray(dI_c, dtype=float)
    m = np.asarray(mask, dtype=bool)
    if not (a.shape == b.shape == m.shape):
        raise ValueError(
            f"images and mask must have one shape, got {a.shape}, {b.shape}, {m.shape}"
        )
    out = a.copy()
    use = m & _valid(b)
    out[use] = b[use]
    return out


def shrunk_box(bbox: ArrayLike, shrink: float = 0.4) -> tuple[int, int, int, int]:
    """Eq. 16: the box shrunk by ``shrink`` (40 %), ``(u_min, v_min, u_max, v_max)`` in pixels.

    ``u_min = floor(u0 + shrink/2 (u2 - u0))``, ``u_max = floor(u2 - shrink/2 (u2 - u0))``, same
    for ``v``: the central ``1 - shrink`` of each side is kept (inclusive pixel bounds).
    """
    b = np.asarray(bbox, dtype=float)
    if b.shape != (4,):
        raise ValueError(f"bbox must be (u0, v0, u2, v2), got shape {b.shape}")
    if not 0.0 <= shrink < 1.0:
        raise ValueError(f"shrink must be in [0, 1), got {shrink}")
    u0, v0, u2, v2 = b
    if u2 < u0 or v2 < v0:
        raise ValueError(f"bbox must satisfy u0 <= u2 and v0 <= v2, got {tuple(b)}")
    a = 0.5 * shrink
    return (
        int(np.floor(a * (u2 - u0) + u0)),
        int(np.floor(a * (v2 - v0) + v0)),
        int(np.floor(a * (u0 - u2) + u2)),
        int(np.floor(a * (v0 - v2) + v2)),
    )


def object_depth(depth_image: ArrayLike, bbox: ArrayLike, shrink: float = 0.4) -> float | None:
    """Eq. 17: mean of the valid (non-zero, finite) depths inside the shrunk box of eq. 16.

    Returns ``None`` when the box holds no valid depth or lies outside the image.
    """
    img = np.asarray(depth_image, dtype=float)
    if img.ndim != 2:
        raise ValueError(f"depth_image must be 2-D (height, width), got shape {img.shape}")
    u_min, v_min, u_max, v_max = shrunk_box(bbox, shrink)
    h, w = img.shape
    u_lo, v_lo = max(u_min, 0), max(v_min, 0)
    u_hi, v_hi = min(u_max, w - 1), min(v_max, h - 1)
    if u_lo > u_hi or v_lo > v_hi:
        return None
    patch = img[v_lo : v_hi + 1, u_lo : u_hi + 1]
    ok = _valid(patch)
    n = int(np.count_nonzero(ok))
    if n == 0:
        return None
    return float(patch[ok].sum() / n)


def object_position(bbox: ArrayLike, depth: float, intrinsics: ArrayLike) -> NDArray[np.float64]:
    """Eq. 18: object position ``[X_o, Y_o, Z_o]`` in the camera frame from the box centre.

    ``Z_o = d_o``, ``X_o = (O_u - cu) d_o / fx``, ``Y_o = (O_v - cv) d_o / fy`` with ``(O_u, O_v)``
    the centre of ``bbox``; ``d_o`` is taken as the camera depth Z (see ``value`` in
    :func:`project_lidar_points`).
    """
    b = np.asarray(bbox, dtype=float)
    if b.shape != (4,):
        raise ValueError(f"bbox must be (u0, v0, u2, v2), got shape {b.shape}")
    if not depth > 0.0:
        raise ValueError(f"depth must be positive, got {depth}")
    fx, fy, cu, cv = _intrinsics(intrinsics)
    ou = 0.5 * (b[0] + b[2])
    ov = 0.5 * (b[1] + b[3])
    return np.array([(ou - cu) * depth / fx, (ov - cv) * depth / fy, float(depth)])
