"""A tiny generation directory written with the library's own writer (no physics)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bicoord_drake.data.episode import (
    EpisodeEntry,
    EpisodeLayout,
    EpisodeMeta,
    EpisodeRecorder,
    Manifest,
    save_episode,
    write_manifest,
)
from bicoord_drake.models.scene import demo_scene

W, H = 64, 48
CAMS = ("head_camera", "left_camera", "right_camera")
TINT = {
    "head_camera": (1.0, 0.6, 0.3),
    "left_camera": (0.3, 1.0, 0.5),
    "right_camera": (0.4, 0.5, 1.0),
}
INSTRUCTION = "Lift the cube together and put it down."


def image(cam: str, t: int) -> np.ndarray:
    """A smooth gradient with a square moving with t: codec-friendly but not constant."""
    y, x = np.mgrid[0:H, 0:W]
    base = 40 + 120 * (x / W) + 60 * (y / H)
    square = (abs(x - (10 + 3 * t) % W) < 6) & (abs(y - H // 2) < 6)
    gray = np.where(square, 235.0, base)
    return np.clip(gray[..., None] * np.array(TINT[cam]), 0, 255).astype(np.uint8)


def episode(length: int, seed: int) -> tuple[EpisodeRecorder, list[list]]:
    """A recorder of `length` frames (both arms moving, left gripper closing) and 2 stage rows."""
    rng = np.random.default_rng(seed)
    rec = EpisodeRecorder(fps=15, initial_action=np.full(14, 0.5))
    K = np.array([[30.0, 0, W / 2], [0, 30.0, H / 2], [0, 0, 1]])
    E = np.hstack([np.eye(3), [[0.0], [0.1], [1.0]]])
    scene = demo_scene("demo")
    for t in range(length):
        s = t / (length - 1)
        action = rng.normal(0.0, 0.3, 14)
        action[6], action[13] = (0.0 if t >= length // 2 else 1.0), 1.0
        rec.add_frame(
            action=action,
            joint_state=action + rng.normal(0.0, 1e-3, 14),
            left_endpose=[-0.3 + 0.1 * s, 0.3, 0.9, 1, 0, 0, 0],
            right_endpose=[0.3 - 0.05 * s, 0.3, 0.9 + 0.02 * s, 0, 1, 0, 0],
            object_poses={
                o.name: [0.1 * s, 0.05 * i, 0.8, 1, 0, 0, 0] for i, o in enumerate(scene.objects)
            },
            images={c: image(c, t) for c in CAMS},
            intrinsic_cv=dict.fromkeys(CAMS, K),
            extrinsic_cv=dict.fromkeys(CAMS, E),
        )
    half = length // 2
    rows = [
        [0, half, "both lift", "grasp the cube", "grasp the cube", 0.5],
        [half, length, "put down", "lower", "idle", 0.5],
    ]
    return rec, rows


def make_dataset(out: Path, lengths: tuple[int, ...] = (12, 9), task: str = "demo_task") -> Path:
    """``out/<task>/default/`` with one episode per length, videos, sidecars and a manifest
    recording one failed seed. Returns ``out``."""
    layout = EpisodeLayout(out, task, "default")
    entries = [EpisodeEntry(seed=7, success=False, reason="PlanningError: no IK solution")]
    for index, length in enumerate(lengths):
        rec, rows = episode(length, seed=index)
        meta = EpisodeMeta(
            task=task,
            seed=index,
            instruction=INSTRUCTION,
            embodiment="aloha_viperx",
            success=True,
            object_count=2,
            scene=demo_scene("demo"),
        )
        save_episode(layout, index, rec, rows, meta)
        entries.append(EpisodeEntry(seed=index, success=True, index=index, frames=length))
    write_manifest(layout.root, Manifest(task=task, config_name="default", episodes=entries))
    return out
