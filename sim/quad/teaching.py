"""Teach-by-showing for ``quad_room``: the keyframe images of a visual path, rendered at the taught
poses (on reset) or stored on disk by ``taskflow teach`` and loaded back (``keyframe_dir``).

The taught poses are the teacher's: they place the camera when the keyframes are rendered and they
serve the world's ground-truth summary; the robot's tasks only ever see the images.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from taskflow_robots.quadcopter import QuadCamera
from taskflow_sim.quad.scene import QuadScene

__all__ = ["load_keyframe_dir", "taught_keyframes", "write_keyframes"]

Pose = tuple[float, float, float, float]


def load_keyframe_dir(path: str | Path) -> tuple[list[NDArray[np.uint8]], dict[str, Any]]:
    """Read the images and ``keyframes.json`` that ``taskflow teach`` wrote (:func:`write_keyframes`); clear
    errors when missing or unreadable."""
    d = Path(path)
    meta_file = d / "keyframes.json"
    if not meta_file.is_file():
        raise ValueError(f"keyframe_dir {str(d)!r}: no keyframes.json (run `taskflow teach` first)")
    try:
        meta = json.loads(meta_file.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{meta_file}: unreadable ({exc})") from exc
    images: list[NDArray[np.uint8]] = []
    for k in meta.get("keyframes", []):
        f = d / k["image"]
        if not f.is_file():
            raise ValueError(f"keyframe image {str(f)!r} is missing")
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is None:
            raise ValueError(f"keyframe image {str(f)!r} is unreadable (not an image OpenCV can decode)")
        images.append(np.asarray(img, dtype=np.uint8)[:, :, ::-1].copy())
    return images, meta


def write_keyframes(out_dir: str | Path, taught: Sequence[tuple[int, Pose]], images: Sequence[NDArray[np.uint8]],
                    camera: QuadCamera, texture_seed: int, name: str = "") -> list[Path]:
    """Store the keyframe ``images`` (RGB) of the ``taught`` ``(id, pose)`` pairs in ``out_dir`` as PNG
    files plus ``keyframes.json`` (poses, camera, texture seed; ``name`` is the mission's name, recorded
    there); returns the written paths (images first, then the JSON)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    entries = []
    for (kid, pose), img in zip(taught, images):
        f = out / f"kf_{kid:03d}.png"
        if not cv2.imwrite(str(f), np.ascontiguousarray(img[:, :, ::-1])):
            raise OSError(f"could not write {f}")
        written.append(f)
        entries.append({"id": kid, "pose": list(pose), "image": f.name})
    meta = {"mission": name, "texture_seed": texture_seed, "keyframes": entries,
            "camera": {"width": camera.width, "height": camera.height, "fovy": camera.fovy, "K": camera.K().tolist()}}
    jf = out / "keyframes.json"
    jf.write_text(json.dumps(meta, indent=1))
    written.append(jf)
    return written


def taught_keyframes(scene: QuadScene, poses: Sequence[Pose], camera: QuadCamera, keyframe_dir: str | None = None
                     ) -> tuple[tuple[NDArray[np.uint8], ...], list[NDArray[np.float64] | None]]:
    """The keyframe images (read-only) and depth buffers of the path taught at ``poses``: rendered in
    ``scene``, or the images loaded from ``keyframe_dir`` (each the camera's size) with depths rendered
    (the depths serve the ground-truth ε only)."""
    depths: list[NDArray[np.float64] | None] = []
    if keyframe_dir is not None:
        images, _ = load_keyframe_dir(keyframe_dir)
        for i, img in enumerate(images):
            if img.shape[:2] != (camera.height, camera.width):
                raise ValueError(f"keyframe {i} is {img.shape[1]}x{img.shape[0]}, the camera is "
                                 f"{camera.width}x{camera.height}")
        depths = [scene.render_with_depth(pose)[1] for pose in poses]
    else:
        images = []
        for pose in poses:
            rgb, depth = scene.render_with_depth(pose)
            images.append(rgb)
            depths.append(depth)
    for img in images:
        img.setflags(write=False)
    return tuple(images), depths
