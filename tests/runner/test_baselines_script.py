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
    assert cells[:18] == [
        "balance_roller",
        "act",
        "state",
        "50",
        "1000",
        "-",  # batch size: not recorded in this (old) result
        "-",  # no extra training arguments
        "10.0 min",
        "0.123",
        "50",
        "-",  # seeds: unknown
        "-",  # skipped: unknown
        "2",
        "10.0",
        "35.0",
        "140.5",
        "lift 60.0; balance 10.0",
        "34.0 / 67.0",
    ]
    assert "lerobot-train t" in text
    header = next(line for line in text.splitlines() if line.startswith("| task"))
    assert len(header.split("|")) == len(row.split("|"))


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
    assert "| jigsaw | diffusion | state | 50 | 10 | - | - | 0.1 min | - | 1 | - | - | - |" in text


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


# ------------------------------------------------------------------ result keys (issue #53, 5)
ACT_ARGS = "--policy.dim_model=128 --policy.n_heads=4"


def _args(baselines, *extra):
    base = ["--data", "d", "--tasks", "balance_roller", "--work", "w", "--out", "o.md"]
    return baselines.parse_args([*base, *extra])


def _result(baselines, tmp_path, args, policy="act", **fields):
    """A result as run_task writes it for `args` (its commands built by the script)."""
    out = tmp_path / baselines.checkpoint_name(policy, args)
    train = baselines.train_command(policy, "balance_roller", tmp_path / "ds", out, args)
    evaluate = baselines.evaluate_command("balance_roller", out, tmp_path / "ev", args)
    result = {
        "task": "balance_roller",
        "policy": policy,
        "inputs": args.inputs,
        **({"resolution": args.resolution} if args.inputs == "images" else {}),
        "demos": args.demos,
        "steps": args.steps,
        "batch_size": args.batch_size,
        "settings": baselines.run_settings(policy, args),
        "train_seconds": 60.0,
        "final_loss": 0.5,
        "n": args.eval_episodes,
        "SR": 0.0,
        "SSR": 0.1,
        "TL": None,
        "stages": [["lift", 0.2]],
        "skipped": 0,
        "skipped_seeds": [],
        "seeds": [100000 * (1 + args.eval_seed) + k for k in range(args.eval_episodes)],
        "diverged": 0,
        "errors": [],
        "commands": {
            "export": "python scripts/export.py",
            "train": baselines.shown(train),
            "evaluate": baselines.shown(evaluate),
        },
        "machine": "m",
        "date": "d",
    }
    result.update(fields)
    return result


def test_every_training_and_evaluation_setting_is_in_the_key(baselines):
    """Two runs that differ in any setting are two results (and two checkpoints); the same
    settings, written with other spacing, are one."""
    base = ["--train-args", f"act={ACT_ARGS}"]
    key = baselines.settings_key("balance_roller", "act", _args(baselines, *base))
    name = baselines.checkpoint_name("act", _args(baselines, *base))
    changed = {
        "batch size": ["--batch-size", "16"],
        "training seed": ["--train-seed", "7"],
        "extra arguments": ["--train-args", "act=--policy.dim_model=256"],
        "evaluation seed": ["--eval-seed", "3"],
        "evaluation rollouts": ["--eval-episodes", "100"],
        "demonstrations": ["--demos", "100"],
        "steps": ["--steps", "50000"],
        "inputs": ["--inputs", "images"],
    }
    for what, extra in changed.items():
        args = _args(baselines, *base, *extra)
        if what == "extra arguments":
            args = _args(baselines, *extra)
        assert baselines.settings_key("balance_roller", "act", args) != key, what
        trains_anew = not what.startswith("evaluation")
        assert (baselines.checkpoint_name("act", args) != name) == trains_anew, what
    images = _args(baselines, "--inputs", "images", "--resolution", "128x96")
    other = _args(baselines, "--inputs", "images", "--resolution", "96x72")
    assert baselines.settings_key("balance_roller", "act", images) != baselines.settings_key(
        "balance_roller", "act", other
    )
    spaced = _args(baselines, "--train-args", "act=--policy.dim_model=128   --policy.n_heads=4")
    assert baselines.settings_key("balance_roller", "act", spaced) == key
    # another policy's extra arguments are not this policy's settings
    both = _args(baselines, *base, "--train-args", "diffusion=--policy.horizon=8")
    assert baselines.settings_key("balance_roller", "act", both) == key
    assert set(baselines.SETTINGS) >= {
        "batch_size",
        "train_args",
        "resolution",
        "eval_seed",
        "eval_episodes",
    }


def test_a_result_s_key_is_its_run_s_and_old_results_are_read_from_their_commands(
    baselines, tmp_path
):
    args = _args(baselines, "--batch-size", "16", "--train-args", f"act={ACT_ARGS}")
    result = _result(baselines, tmp_path, args)
    key = baselines.settings_key("balance_roller", "act", args)
    assert baselines.result_key(result) == key
    old = {k: v for k, v in result.items() if k not in ("settings", "skipped_seeds", "seeds")}
    assert baselines.settings_of(old) == result["settings"]
    assert baselines.result_key(old) == key
    diffusion = _args(baselines, "--train-args", "diffusion=--policy.down_dims=[32,64,128]")
    result = _result(baselines, tmp_path, diffusion, policy="diffusion")
    old = {k: v for k, v in result.items() if k != "settings"}
    assert baselines.settings_of(old)["train_args"] == "'--policy.down_dims=[32,64,128]'"
    assert baselines.result_key(old) == baselines.result_key(result)


def test_latest_result_per_key_and_a_rerun_skips_only_equal_keys(baselines, tmp_path):
    b8, b16 = _args(baselines), _args(baselines, "--batch-size", "16")
    first = _result(baselines, tmp_path, b8, SR=0.1)
    other = _result(baselines, tmp_path, b16, SR=0.2)
    again = _result(baselines, tmp_path, b8, SR=0.3)
    latest = baselines.latest_results([first, other, again])
    assert [r["SR"] for r in latest] == [0.3, 0.2]  # one row per key, the last written
    done = {baselines.result_key(r) for r in [first]}
    assert baselines.settings_key("balance_roller", "act", b8) in done
    assert baselines.settings_key("balance_roller", "act", b16) not in done
    assert baselines.settings_key("balance_roller", "diffusion", b8) not in done


def test_the_table_shows_batch_size_extra_arguments_seeds_and_skipped_seeds(baselines, tmp_path):
    args = _args(baselines, "--batch-size", "16", "--eval-episodes", "3")
    plain = _result(baselines, tmp_path, args)
    extra = _args(baselines, "--eval-episodes", "3", "--train-args", f"act={ACT_ARGS}")
    skipping = _result(
        baselines,
        tmp_path,
        extra,
        seeds=[100000, 100002, 100004],
        skipped=2,
        skipped_seeds=[100001, 100003],
    )
    text = baselines.markdown([plain, skipping], "cmd")
    header = next(line for line in text.splitlines() if line.startswith("| task"))
    columns = [c.strip() for c in header.strip("|").split("|")]
    rows = [
        dict(zip(columns, (c.strip() for c in line.strip("|").split("|")), strict=True))
        for line in text.splitlines()
        if line.startswith("| balance_roller")
    ]
    assert [r["batch"] for r in rows] == ["16", "8"]
    assert [r["train args"] for r in rows] == ["-", "a1"]
    assert f"- a1: `{ACT_ARGS}`" in text
    assert [r["seeds"] for r in rows] == ["100000-100002", "100000-100004"]
    assert [r["skipped"] for r in rows] == ["0", "2: 100001, 100003"]
    assert "### balance_roller, act (state), 20000 steps, batch 8, train args a1" in text
    # an old result without the seeds: the range from its evaluation seed, count and skips
    old = {k: v for k, v in skipping.items() if k not in ("settings", "seeds", "skipped_seeds")}
    assert baselines.seeds_text(old) == "100000-100004" and baselines.skipped_text(old) == "2"
