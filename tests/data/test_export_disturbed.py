"""LeRobot export of disturbed demonstrations (issue #54, item 3): the per-frame ``disturbed``
marker is 1 over exactly each recovery row's frames, 0 elsewhere and on clean episodes, and a
dataset without a disturbed episode has no such feature (needs [lerobot]; no physics)."""

import json

import numpy as np
import pytest

from bicoord_drake.data import export
from bicoord_drake.data.episode import EpisodeLayout, EpisodeMeta, read_episode, save_episode
from bicoord_drake.models.scene import demo_scene
from bicoord_drake.sim.disturbances import Disturbance, disturbance_records, recovery_row
from tests.data.synthetic import INSTRUCTION, episode, make_dataset

pytest.importorskip(
    "lerobot.datasets.lerobot_dataset",
    reason="the [lerobot] extra is not installed (see README: LeRobot export)",
)

PUSH = Disturbance(
    kind="push", step=3, duration=2, body="red_cube", force=(0.0, 0.8, 0.0), point=(0, 0, -0.01)
)
RECOVERY_END = 7  # the expert's next plan: frames 3-6 are the recovery row


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A clean episode of 12 frames (seed 0) and a pushed one of 10 (seed 1)."""
    root = make_dataset(tmp_path_factory.mktemp("src"), lengths=(12,))
    rec, rows = episode(10, seed=1)
    rec.disturbances = disturbance_records([PUSH])
    rec.recovery_rows = [recovery_row(PUSH, RECOVERY_END)]
    meta = EpisodeMeta(
        task="demo_task",
        seed=1,
        instruction=INSTRUCTION,
        embodiment="aloha_viperx",
        success=True,
        object_count=2,
        scene=demo_scene("demo"),
        extra={"disturb": "push"},
    )
    save_episode(EpisodeLayout(root, "demo_task", "default"), 1, rec, rows, meta)
    return root


def test_the_marker_is_the_recovery_rows_frames(source):
    clean, pushed = export.load_episodes([source], images=False)
    assert pushed.recovery == [recovery_row(PUSH, RECOVERY_END)]
    want = np.zeros(10, np.int8)
    want[3:7] = 1
    assert np.array_equal(export.disturbed_frames(pushed), want)
    assert np.array_equal(export.disturbed_frames(clean), np.zeros(12, np.int8))
    assert export.is_disturbed(pushed) and not export.is_disturbed(clean)


@pytest.mark.parametrize("codebase", ["v3.0", "v2.1"])
def test_a_disturbed_dataset_marks_exactly_the_recovery_frames(source, tmp_path, codebase):
    episodes = export.load_episodes([source], images=False)
    result = export.export_lerobot(
        [source], tmp_path / "lr", codebase=codebase, dtype="float64", images=False
    )
    info = json.loads((result.root / "meta/info.json").read_text())
    assert info["features"][export.DISTURBED]["dtype"] == "int8"
    root = result.root
    if codebase == "v2.1":
        root = export.convert_v21_to_v30(result.root, result.repo_id, tmp_path / "work")
    dataset = export.load_lerobot(root, result.repo_id)
    check = export.check_export(dataset, episodes)
    assert check.ok and check.numeric_exact[export.DISTURBED]
    marks = [int(dataset[i][export.DISTURBED]) for i in range(dataset.num_frames)]
    assert marks[:12] == [0] * 12  # the clean episode: zeros
    assert marks[12:] == [0, 0, 0, 1, 1, 1, 1, 0, 0, 0]  # [push.step, recovery end)
    extras = [json.loads(line) for line in (result.root / export.EXTRAS_FILE).open()]
    assert "disturbances" not in extras[0] and "recovery" not in extras[0]
    assert extras[1]["disturbances"] == disturbance_records([PUSH])
    assert extras[1]["recovery"] == [recovery_row(PUSH, RECOVERY_END)]


def test_without_a_disturbed_episode_the_dataset_has_no_marker(source, tmp_path):
    clean = source / "demo_task" / "default" / "data" / "episode0.hdf5"
    assert read_episode(clean, images=False).disturbances == []
    result = export.export_lerobot([clean], tmp_path / "lr", images=False)
    info = json.loads((result.root / "meta/info.json").read_text())
    assert export.DISTURBED not in info["features"]
    assert set(export.lerobot_features(read_episode(clean), images=False)) == set(export.NUMERIC)
    line = json.loads((result.root / export.EXTRAS_FILE).read_text())
    assert set(line) == {"episode_index", "source", "task_name", "seed", "instruction", "stages"}
