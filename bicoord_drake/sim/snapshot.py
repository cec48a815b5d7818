"""Render the cell from all cameras to PNG files and a labelled contact sheet."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from bicoord_drake.config import StationConfig
from bicoord_drake.models.layout import action_layout
from bicoord_drake.models.robots import get_embodiment
from bicoord_drake.models.scene import Scene
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station

#: Named arm poses, both the embodiment's own data: ``home`` and ``reach``
#: (``Embodiment.reach_pose``: leaning over the table; home if the embodiment has none).
ARM_POSES: tuple[str, ...] = ("home", "reach")


def pose_action(config: StationConfig, pose: str) -> np.ndarray:
    """The action holding both arms of `config`'s embodiment at a named pose, grippers open."""
    if pose not in ARM_POSES:
        raise ValueError(f"unknown pose {pose!r}; choose one of: {', '.join(ARM_POSES)}")
    embodiment = get_embodiment(config.embodiment)
    if pose == "home" or embodiment.reach_pose is None:
        return embodiment.home_action()
    left, right = (np.array(q, dtype=float) for q in embodiment.reach_pose)
    return action_layout(embodiment).compose(
        {"left": left, "right": right}, {"left": 1.0, "right": 1.0}
    )


def render_snapshot(
    scene: Scene,
    out_dir: str | Path,
    config: StationConfig | None = None,
    pose: str = "reach",
    settle_seconds: float = 1.0,
) -> dict[str, Path]:
    """Build `scene`, move both arms to `pose`, let it settle, and write one PNG per camera
    (plus 16-bit depth PNGs if enabled) and ``contact_sheet.png``. Returns name -> path."""
    config = config or StationConfig()
    action = pose_action(config, pose)
    sim = Simulation(build_station(scene, config))
    for _ in range(max(1, round(settle_seconds * config.control_rate))):
        sim.step(action)
    images = sim.images(depth=config.cameras.depth)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = {
        name: _save_png(Image.fromarray(img), out / f"{name}.png") for name, img in images.items()
    }
    rgb = [(n, images[n]) for n in sim.station.cameras]
    written["contact_sheet"] = _save_png(contact_sheet(rgb), out / "contact_sheet.png")
    return written


def contact_sheet(images: list[tuple[str, np.ndarray]]) -> Image.Image:
    """Images side by side, each captioned with its name."""
    h = max(img.shape[0] for _, img in images)
    w = sum(img.shape[1] for _, img in images)
    sheet = Image.new("RGB", (w, h + 18), "white")
    draw = ImageDraw.Draw(sheet)
    x = 0
    for name, img in images:
        sheet.paste(Image.fromarray(img), (x, 18))
        draw.text((x + 4, 3), name, fill="black")
        x += img.shape[1]
    return sheet


def _save_png(image: Image.Image, path: Path) -> Path:
    """Write atomically: a partial PNG never appears under the final name."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".png.tmp")
    os.close(fd)
    try:
        image.save(tmp, format="PNG")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return path
