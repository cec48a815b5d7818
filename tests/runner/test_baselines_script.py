"""benchmarks/baselines.py: its commands and its table (the run itself is smoke-tested by hand;
the loop it automates is tests/policies/test_lerobot_loop.py)."""

import sys

import pytest

from tests.runner.benchmark_scripts import load_benchmark


@pytest.fixture(scope="module")
def baselines():
    return load_benchmark("baselines")


def test_commands_are_state_based_and_carry_the_extra_arguments(baselines, tmp_path):
    args = baselines.parse_args(
        ["--data", "d", "--tasks", "jigsaw,cook", "--work", "w", "--out", "o.md"]
        + ["--steps", "100", "--train-args", "diffusion=--policy.horizon=8"]
    )
    assert args.tasks == ["jigsaw", "cook"] and args.policies == ["act", "diffusion"]
    export = baselines.export_command([tmp_path / "e0.hdf5"], tmp_path / "ds", args.inputs)
    assert export[-2:] == ["--environment-state", "--no-images"]
    assert str(tmp_path / "e0.hdf5") in export
    train = baselines.train_command("diffusion", "jigsaw", tmp_path / "ds", tmp_path / "out", args)
    assert "--policy.type=diffusion" in train and "--policy.horizon=8" in train
    assert "--steps=100" in train and "--policy.device=cpu" in train
    assert train[-1] == f"--output_dir={tmp_path / 'out'}"
    act = baselines.train_command("act", "jigsaw", tmp_path / "ds", tmp_path / "out", args)
    assert "--policy.horizon=8" not in act
    evaluate = baselines.evaluate_command("jigsaw", tmp_path / "out", tmp_path / "ev", args)
    assert ["--split", "unseen"] == evaluate[evaluate.index("--split") :][:2]
    assert "--no-render" in evaluate and f"lerobot:{tmp_path / 'out'}" in evaluate
    images = baselines.parse_args(
        ["--data", "d", "--tasks", "jigsaw", "--work", "w", "--out", "o.md"]
        + ["--inputs", "images", "--resolution", "96x72"]
    )
    export = baselines.export_command([tmp_path / "e0.hdf5"], tmp_path / "ds", images.inputs)
    assert "--no-images" not in export and "--environment-state" not in export
    evaluate = baselines.evaluate_command("jigsaw", tmp_path / "out", tmp_path / "ev", images)
    assert "--no-render" not in evaluate
    assert evaluate[evaluate.index("--resolution") + 1] == "96x72"
    assert baselines.shown([sys.executable, "x"]) == "python x"
    with pytest.raises(SystemExit):
        baselines.parse_args(
            ["--data", "d", "--tasks", "t", "--work", "w", "--out", "o"] + ["--policies", "pi0"]
        )


def test_export_names_the_source_directory_when_the_demos_are_its_first_files(baselines, tmp_path):
    from tests.data.synthetic import make_dataset

    make_dataset(tmp_path, lengths=(3,) * 11)
    files = sorted((tmp_path / "demo_task").rglob("*.hdf5"), key=lambda p: int(p.stem[7:]))
    source = baselines.common_source(files[:10])
    assert source is not None and files[0].is_relative_to(source)
    export = baselines.export_command(files[:10], tmp_path / "ds", "state", source)
    assert export[2:5] == [str(source), "--max-episodes", "10"]
    assert baselines.common_source([files[0], files[2]]) is None  # not a prefix: list them


def test_table_rows(baselines):
    result = {
        "task": "balance_roller",
        "policy": "act",
        "demos": 50,
        "steps": 1000,
        "train_seconds": 600.0,
        "final_loss": 0.1234,
        "n": 50,
        "diverged": 2,
        "SR": 0.1,
        "SSR": 0.35,
        "TL": 140.5,
        "stages": [["lift", 0.6], ["balance", 0.1]],
        "errors": [],
        "commands": {"export": "python e", "train": "lerobot-train t", "evaluate": "python v"},
        "machine": "cpu, 2 cores",
        "date": "2026-11-26 09:00 UTC",
    }
    text = baselines.markdown([result], "python benchmarks/baselines.py ...")
    row = next(line for line in text.splitlines() if line.startswith("| balance_roller"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[:14] == [
        "balance_roller",
        "act",
        "state",
        "50",
        "1000",
        "10.0 min",
        "0.123",
        "50",
        "2",
        "10.0",
        "35.0",
        "140.5",
        "lift 60.0; balance 10.0",
        "34.0 / 67.0",
    ]
    assert "lerobot-train t" in text


def test_notes_stand_between_the_table_and_the_commands(baselines):
    result = {
        "task": "jigsaw",
        "policy": "diffusion",
        "demos": 50,
        "steps": 10,
        "train_seconds": 6.0,
        "final_loss": None,
        "n": 1,
        "SR": 0.0,
        "SSR": 0.0,
        "TL": None,
        "stages": [],
        "errors": [],
        "commands": {"export": "e", "train": "t", "evaluate": "v"},
        "machine": "m",
        "date": "d",
    }
    text = baselines.markdown([result], "cmd", "## Notes\n\nundertrained")
    assert text.index("| jigsaw |") < text.index("undertrained") < text.index("## Commands")
    assert "| jigsaw | diffusion | state | 50 | 10 | 0.1 min | - | 1 | - |" in text


def test_a_finished_training_is_reused_only_by_the_same_command(baselines, tmp_path):
    out = tmp_path / "ckpt"
    out.mkdir()
    train = ["lerobot-train", "--steps=10"]
    assert baselines.trained(out, train) is None  # nothing recorded: train
    baselines.write_json_atomic(
        out / baselines.TRAINED, {"command": baselines.shown(train), "seconds": 12.5}
    )
    assert baselines.trained(out, train) == 12.5
    assert baselines.trained(out, ["lerobot-train", "--steps=20"]) is None


def test_tasks_are_required_unless_only_the_table_is_rewritten(baselines):
    with pytest.raises(SystemExit):
        baselines.parse_args(["--work", "w", "--out", "o.md"])
    assert baselines.parse_args(["--work", "w", "--out", "o.md", "--table-only"]).tasks == []
