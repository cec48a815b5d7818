#!/usr/bin/env python
"""Planning time with and without rebuilding unchanged held-object shapes in the checker.

    python benchmarks/bench_checker_sync.py
    python benchmarks/bench_checker_sync.py --cases jigsaw:franka_pair:0,jigsaw:aloha_viperx:0

The planning model puts each held object's collision shapes on its gripper in Drake's
``SceneGraphCollisionChecker`` (``PlanningModel._sync_checker_held``), and every change of the
holds (an attach, a detach, a merged motion checking each arm with what it carries, an object
ignored for a move) syncs them. Adding a shape costs milliseconds. The package keeps a
gripper's shapes when its hold is unchanged; the *rebuild* runs restore the earlier behaviour
(every sync removes and re-adds every shape and resets the hands' filters) by forgetting what
the checker carries before each sync.

For each case (task, robot, seed) the expert runs in physics without cameras once in each
mode, alternating, ``--repeats`` times; the table gives the median planning seconds
(``run_expert``'s timings: the expert's own time between control steps), the ratio, and
whether both modes recorded the same actions (sha256 of the action array): the change must
not alter any plan. The result file is rewritten (a temporary file, then renamed).
"""

from __future__ import annotations

import argparse
import hashlib
import statistics
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # measure this checkout's code
sys.path.insert(0, str(ROOT / "benchmarks"))
import expert_success  # noqa: E402  (its sibling: git state and machine line)

DEFAULT_CASES = (
    "place_plate_and_cup:franka_pair:0",
    "jigsaw:franka_pair:0",
    "exchange_mics:franka_pair:0",
    "place_plate_and_cup:aloha_viperx:0",
    "jigsaw:aloha_viperx:0",
    "exchange_mics:aloha_viperx:0",
)
MODES = ("keep", "rebuild")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--cases", default=",".join(DEFAULT_CASES), help="comma list of TASK:ROBOT:SEED"
    )
    parser.add_argument("--repeats", type=int, default=1, help="runs per case and mode")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "bench_checker_sync.md")
    args = parser.parse_args(argv)
    cases = []
    for text in args.cases.split(","):
        parts = text.strip().split(":")
        if len(parts) != 3 or not parts[2].isdigit():
            parser.error(f"--cases: {text!r} is not TASK:ROBOT:SEED")
        cases.append((parts[0], parts[1], int(parts[2])))
    if args.repeats < 1:
        parser.error("--repeats must be at least 1")
    args.cases = cases
    return args


def forget_checker_state() -> None:
    """Make every later sync rebuild the shapes and filters, as before the change."""
    from bicoord_drake.planning.model import SIDES, PlanningModel

    keep = PlanningModel._sync_checker_held

    def rebuild(self: PlanningModel) -> None:
        self._checker_held = dict.fromkeys(SIDES, ("", b"stale"))
        self._checker_together = None
        keep(self)

    rebuild.keep = keep  # type: ignore[attr-defined]
    PlanningModel._sync_checker_held = rebuild


def restore_checker_state() -> None:
    from bicoord_drake.planning.model import PlanningModel

    keep = getattr(PlanningModel._sync_checker_held, "keep", None)
    if keep is not None:
        PlanningModel._sync_checker_held = keep


def run_case(task: str, robot: str, seed: int, mode: str) -> dict:
    """One expert episode in `mode`: success, planning and wall seconds, action digest."""
    from bicoord_drake.config import StationConfig
    from bicoord_drake.episode_setup import EpisodeSetup
    from bicoord_drake.runner.generate import run_expert

    (forget_checker_state if mode == "rebuild" else restore_checker_state)()
    try:
        setup = EpisodeSetup(
            task=task,
            seed=seed,
            embodiment=robot,
            station=StationConfig(embodiment=robot, render=False),
        )
        start = time.perf_counter()
        result = run_expert(setup)
        wall = time.perf_counter() - start
    finally:
        restore_checker_state()
    actions = result.recorder.actions if result.recorder is not None else None
    return {
        "success": result.success,
        "reason": result.reason,
        "planning": float(result.timings.get("planning", float("nan"))),
        "wall": wall,
        "sha": None if actions is None else hashlib.sha256(actions.tobytes()).hexdigest(),
    }


def commit_text() -> str:
    """The commit measured, marked when the package differs from it."""
    head, dirty = expert_success.git_state(ROOT)
    return head[:7] + (" (with uncommitted changes)" if dirty else "")


def markdown(rows: list[dict], command: str) -> str:
    lines = [
        "# bench_checker_sync: held-object shapes kept in the collision checker",
        "",
        __doc__.split("\n\n", 2)[2].split("\n\nFor each case")[0].replace("\n", " ").strip(),
        "",
        "| task | robot | seed | planning s, keep | planning s, rebuild | rebuild / keep | "
        "wall s, keep | wall s, rebuild | same actions | kept |",
        "|---|---|---:|---:|---:|---:|---:|---:|---|---|",
    ]
    for r in rows:
        ratio = r["rebuild"]["planning"] / r["keep"]["planning"]
        lines.append(
            f"| {r['task']} | {r['robot']} | {r['seed']} | {r['keep']['planning']:.2f} | "
            f"{r['rebuild']['planning']:.2f} | {ratio:.2f} | {r['keep']['wall']:.1f} | "
            f"{r['rebuild']['wall']:.1f} | {'yes' if r['same'] else '**no**'} | "
            f"{r['keep']['success']} / {r['rebuild']['success']} |"
        )
    keep = sum(r["keep"]["planning"] for r in rows)
    rebuild = sum(r["rebuild"]["planning"] for r in rows)
    lines += [
        "",
        f"All cases: planning {rebuild:.1f} s rebuilding against {keep:.1f} s keeping "
        f"({rebuild / keep:.2f}x).",
        "",
        f"Medians of {rows[0]['repeats']} run(s) per case and mode, the modes alternating. "
        f"Machine: {expert_success.machine()}. Commit: {commit_text()}. "
        f"Date: {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC.",
        "",
        "Command:",
        "",
        f"    {command}",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    command = "python benchmarks/bench_checker_sync.py " + " ".join(
        sys.argv[1:] if argv is None else argv
    )
    rows = []
    for task, robot, seed in args.cases:
        runs: dict[str, list[dict]] = {m: [] for m in MODES}
        for _ in range(args.repeats):
            for mode in MODES:
                run = run_case(task, robot, seed, mode)
                runs[mode].append(run)
                print(
                    f"{task} {robot} {seed} {mode}: planning {run['planning']:.2f} s, "
                    f"wall {run['wall']:.1f} s, kept {run['success']} {run['reason'] or ''}",
                    flush=True,
                )
        shas = {r["sha"] for m in MODES for r in runs[m]}
        row = {"task": task, "robot": robot, "seed": seed, "repeats": args.repeats}
        for mode in MODES:
            row[mode] = {
                "planning": statistics.median(r["planning"] for r in runs[mode]),
                "wall": statistics.median(r["wall"] for r in runs[mode]),
                "success": all(r["success"] for r in runs[mode]),
            }
        row["same"] = len(shas) == 1 and None not in shas
        rows.append(row)
    text = markdown(rows, command.strip())
    tmp = args.out.with_suffix(args.out.suffix + ".tmp")
    tmp.write_text(text)
    tmp.replace(args.out)
    print(f"wrote {args.out}")
    return 0 if all(r["same"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
