"""LeRobot export: the dataset loads with lerobot and equals its source (needs [lerobot])."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from bicoord_drake.data import export
from tests.data.synthetic import INSTRUCTION, make_dataset

pytest.importorskip(
    "lerobot.datasets.lerobot_dataset",
    reason="the [lerobot] extra is not installed (see README: LeRobot export)",
)

ROOT = Path(__file__).resolve().parents[2]
MAX_IMAGE_ERROR = 6.0  # mean |error| per frame, 0..255 levels: codec tolerance


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("src"))


@pytest.fixture(scope="module")
def episodes(source):
    return export.load_episodes([source])


def assert_matches(check: export.ExportCheck, lengths=(12, 9)) -> None:
    assert check.frame_counts == tuple((n, n) for n in lengths)
    assert check.numeric_exact == dict.fromkeys(check.numeric_exact, True)
    assert set(check.numeric_exact) == {
        "observation.state",
        "action",
        "observation.endpose",
        "stage_index",
    }
    assert check.images_compared == 3 * sum(lengths)
    assert check.image_max_mean_abs_error < MAX_IMAGE_ERROR


def test_v30_export_loads_and_equals_the_source(source, episodes, tmp_path):
    result = export.export_lerobot([source], tmp_path / "lr", dtype="float64")
    assert (result.episodes, result.frames, result.repo_id) == (2, 21, "bicoord_drake/demo_task")
    info = json.loads((result.root / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["fps"] == 15
    dataset = export.load_lerobot(result.root, result.repo_id)
    assert dataset.num_episodes == 2 and dataset.num_frames == 21
    assert_matches(export.check_export(dataset, episodes, images_per_episode=None))
    # the stored columns are bit-exact float64 (checked above); items come out as float32
    item = dataset[12 + 5]  # episode 1, frame 5
    assert item["task"] == INSTRUCTION
    want = episodes[1].joint_action[5].astype(np.float32)
    assert np.array_equal(item["action"].numpy(), want)
    want = episodes[1].joint_state[5].astype(np.float32)
    assert np.array_equal(item["observation.state"].numpy(), want)
    assert int(item["stage_index"]) == episodes[1].stage_index[5] == 1
    assert item["observation.images.head"].shape == (3, 48, 64)
    extras = [json.loads(line) for line in (result.root / export.EXTRAS_FILE).open()]
    assert [e["stages"] for e in extras] == [e.stages for e in episodes]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no staging left


def test_float32_export_equals_the_source_cast_to_float32(source, episodes, tmp_path):
    result = export.export_lerobot([source], tmp_path / "lr")
    dataset = export.load_lerobot(result.root, result.repo_id)
    assert dataset.meta.features["action"]["dtype"] == "float32"
    assert_matches(export.check_export(dataset, episodes, images_per_episode=None))
    item = dataset[3]
    assert np.array_equal(item["action"].numpy(), episodes[0].joint_action[3].astype(np.float32))


def test_check_notices_a_different_source(source, episodes, tmp_path):
    result = export.export_lerobot([source], tmp_path / "lr", dtype="float64")
    dataset = export.load_lerobot(result.root, result.repo_id)
    swapped = export.check_export(dataset, episodes[::-1], images_per_episode=1)
    assert swapped.frame_counts == ((12, 9), (9, 12)) and not swapped.ok


def test_v21_export_converts_with_lerobots_converter(source, episodes, tmp_path):
    result = export.export_lerobot([source], tmp_path / "lr21", codebase="v2.1", dtype="float64")
    info = json.loads((result.root / "meta/info.json").read_text())
    assert info["codebase_version"] == "v2.1" and info["total_episodes"] == 2
    assert (result.root / "data/chunk-000/episode_000001.parquet").is_file()
    assert (result.root / "videos/chunk-000/observation.images.left/episode_000000.mp4").is_file()
    converted = export.convert_v21_to_v30(result.root, result.repo_id, tmp_path / "work")
    dataset = export.load_lerobot(converted, result.repo_id)
    assert_matches(export.check_export(dataset, episodes, images_per_episode=None))
    assert dataset[0]["task"] == INSTRUCTION


def test_bad_requests_say_what_is_wrong(source, tmp_path):
    (tmp_path / "taken").mkdir()
    with pytest.raises(FileExistsError, match="exists"):
        export.export_lerobot([source], tmp_path / "taken")
    with pytest.raises(ValueError, match="v3.0, v2.1"):
        export.export_lerobot([source], tmp_path / "a", codebase="v4")
    with pytest.raises(ValueError, match="float32, float64"):
        export.export_lerobot([source], tmp_path / "b", dtype="int8")
    with pytest.raises(ValueError, match="no such file"):
        export.export_lerobot([tmp_path / "missing"], tmp_path / "c")
    assert not (tmp_path / "a").exists() and not (tmp_path / "c").exists()


def load_script(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_cli_exports_and_checks(source, tmp_path, capsys):
    main = load_script("export").main
    args = [str(source), "--to", "lerobot", "--out", str(tmp_path / "cli")]
    assert main([*args, "--codebase", "v2.1", "--check"]) == 0
    out = capsys.readouterr().out
    assert "2 episodes, 21 frames" in out and "frame counts match" in out
    assert "exact: observation.state, action, observation.endpose, stage_index" in out
    assert main(args) == 1
    assert "exists" in capsys.readouterr().err


# ------------------------------------------------------------------ environment state
def test_environment_state_is_the_task_objects_poses(source, tmp_path):
    from bicoord_drake.data.environment_state import ENVIRONMENT_STATE, feature_names

    episodes = export.load_episodes([source], images=False, environment_state=True)
    objects = ("red_cube", "green_cube", "blue_cube", "bowl")  # the demo scene's order
    result = export.export_lerobot(
        [source], tmp_path / "lr", dtype="float64", images=False, environment_state=True
    )
    info = json.loads((result.root / "meta/info.json").read_text())
    feature = info["features"][ENVIRONMENT_STATE]
    assert feature["shape"] == [28] and feature["names"] == feature_names(objects)
    assert feature["names"][:8] == [
        *(f"red_cube_{f}" for f in "x y z qw qx qy qz".split()),
        "green_cube_x",
    ]
    assert not any(k.startswith("observation.images") for k in info["features"])
    dataset = export.load_lerobot(result.root, result.repo_id)
    check = export.check_export(dataset, episodes)
    assert check.ok and check.numeric_exact[ENVIRONMENT_STATE] and check.images_compared == 0
    for episode_index, t in [(0, 0), (0, 11), (1, 4)]:
        item = dataset[12 * episode_index + t]
        want = np.concatenate([episodes[episode_index].objects[n][t] for n in objects])
        assert np.allclose(item[ENVIRONMENT_STATE].numpy(), want, atol=1e-7)
    assert np.allclose(dataset[11][ENVIRONMENT_STATE].numpy()[:3], [0.1, 0.0, 0.8])
    assert np.allclose(dataset[11][ENVIRONMENT_STATE].numpy()[7:10], [0.1, 0.05, 0.8])


def test_environment_state_in_v21_and_the_cli(source, tmp_path, capsys):
    main = load_script("export").main
    out = tmp_path / "cli"
    args = [str(source), "--to", "lerobot", "--out", str(out), "--codebase", "v2.1"]
    assert main([*args, "--environment-state", "--no-images", "--check"]) == 0
    assert "exact: observation.state, action, observation.endpose, stage_index, " in (
        capsys.readouterr().out
    )
    info = json.loads((out / "meta/info.json").read_text())
    assert info["features"]["observation.environment_state"]["shape"] == [28]
    assert info["total_videos"] == 0


def test_max_episodes_takes_the_first_files_in_seed_order(tmp_path):
    lengths = tuple(range(3, 14))  # 11 episodes: episode10 comes after episode9
    source = make_dataset(tmp_path / "src", lengths=lengths)
    first = export.load_episodes([source], images=False, max_episodes=10)
    assert [len(e.joint_action) for e in first] == list(lengths[:10])
    with pytest.raises(ValueError, match="12 episodes asked for, 11 found"):
        export.load_episodes([source], images=False, max_episodes=12)
