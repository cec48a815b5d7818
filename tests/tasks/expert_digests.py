"""Digests of the experts' actions in physics: the check that a refactor left every plan intact.

For each (task, seed) in :data:`CASES` the expert runs in physics exactly as the generator runs
it (:func:`bicoord_drake.runner.generate.run_expert`, no rendering), and the SHA-256 of its
action array ((T, 14) float64 bytes) is compared with the one committed in
``expert_digests.json``. Equal digests mean the same commands were sent at every control step,
bit for bit. ``tests/tasks/test_expert_digests.py`` (slow) runs the comparison.

Commands (from the repository root, one process, about 8-12 min on 2 cores)::

    nice -n 10 python -m tests.tasks.expert_digests            # compare with the committed file
    nice -n 10 python -m tests.tasks.expert_digests --record   # re-record after an intended change
    nice -n 10 python -m tests.tasks.expert_digests --record-missing  # only cases new to CASES
    nice -n 10 python -m tests.tasks.expert_digests --tasks clean_table,collect_pens  # a subset

Re-record only when a plan is *meant* to change (a new skill parameter, a new effort limit in
models/embodiment.py, a changed scene): run the comparison first to see which cases differ,
re-record, and commit the new ``expert_digests.json`` together with the change and the
reason in the commit message. A refactor must pass without re-recording.

The digests hold on one machine, not across machines: the physics and the planners' floating
point differ in the last bits between CPUs, and a last bit can tip an expert's branch. On the
machine of 2026-12-07 (a new one; drake 1.51.1, numpy 2.4.6, ruckig 0.19.4, scipy 1.17.1) the
unchanged package differed from the digests recorded on the earlier one in all 35 cases (33
with the same number of steps; cook seed 2 took 590 steps instead of 542, exchange_pots seed
3 435 instead of 432); they were re-recorded there from the unchanged package. Before reading
a difference as a change of plan, run the comparison at the last commit on the same machine.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

from bicoord_drake.config import StationConfig
from bicoord_drake.episode_setup import EpisodeSetup
from bicoord_drake.runner.generate import run_expert
from bicoord_drake.tasks import get_task

#: The committed digests.
DIGEST_FILE = Path(__file__).with_name("expert_digests.json")

#: Seeds other than (0, 2) where one of those fails with the current experts (exchange_pots
#: seed 2 under the #31 physics; cook seed 0 with the package versions of 2026-12-05).
OTHER_SEEDS = {"exchange_pots": (0, 3), "cook": (2,)}

#: (task, seed) pairs; every one of them succeeds with the current experts.
CASES: tuple[tuple[str, int], ...] = tuple(
    (task, seed)
    for task in (
        "jigsaw",
        "exchange_mics",
        "handover_block_with_bowls",
        "cook",
        "balance_roller",
        "stack_bowls",
        "build_tower_with_blocks",
        "place_plate_and_cup",
        "clean_table",
        "build_bridge",
        "collect_pens",
        "divide_block_tower",
        "exchange_pots",
        "extract_bottom_block_to_top",
        "fetch_block_with_roller",
        "put_objects_cabinet",
        "match_blocks_with_signs",
        "sweep_block",
    )
    for seed in OTHER_SEEDS.get(task, (0, 2))
)


def case_key(task: str, seed: int) -> str:
    return f"{task}/{seed}"


def select_cases(tasks: str | None) -> tuple[tuple[str, int], ...]:
    """The cases of the comma-separated `tasks` (all cases for None); unknown names raise
    ValueError listing the tasks that have cases."""
    if not tasks:
        return CASES
    known = sorted({t for t, _ in CASES})
    wanted = [t.strip() for t in tasks.split(",") if t.strip()]
    unknown = [t for t in wanted if t not in known]
    if unknown:
        raise ValueError(f"no digest cases for {unknown}; tasks with cases: {', '.join(known)}")
    return tuple(c for c in CASES if c[0] in wanted)


def expert_digest(task: str, seed: int) -> dict:
    """Run `task`'s expert for `seed` in physics; its step count and action digest.

    Raises RuntimeError if the episode fails (a failed run records no actions to compare).
    """
    result = run_expert(
        EpisodeSetup(task=get_task(task), seed=seed, station=StationConfig(render=False))
    )
    if not result.success or result.recorder is None:
        raise RuntimeError(f"{task} seed {seed} failed: {result.reason}")
    actions = result.recorder.actions
    return {"steps": int(actions.shape[0]), "sha256": hashlib.sha256(actions.tobytes()).hexdigest()}


def load_digests(path: Path = DIGEST_FILE) -> dict[str, dict]:
    return json.loads(path.read_text())


def compare(cases=CASES, path: Path = DIGEST_FILE) -> list[str]:
    """Run every case; one line per case whose digest differs from the committed one."""
    committed = load_digests(path)
    diffs = []
    for task, seed in cases:
        key = case_key(task, seed)
        if key not in committed:
            diffs.append(f"{key}: no committed digest (re-record)")
            continue
        got = expert_digest(task, seed)
        print(f"{key}: {got['steps']} steps {got['sha256'][:16]}", flush=True)
        if got != committed[key]:
            diffs.append(f"{key}: committed {committed[key]}, now {got}")
    return diffs


def record(cases=CASES, path: Path = DIGEST_FILE, only_missing: bool = False) -> dict[str, dict]:
    """Run every case (with `only_missing`, only those without a committed digest, keeping the
    others as committed) and write the digests (temp file, then rename)."""
    digests = load_digests(path) if only_missing and path.exists() else {}
    for task, seed in cases:
        if case_key(task, seed) in digests:
            continue
        digests[case_key(task, seed)] = got = expert_digest(task, seed)
        print(f"{case_key(task, seed)}: {got['steps']} steps {got['sha256'][:16]}", flush=True)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(digests, indent=2) + "\n")
    tmp.replace(path)
    return digests


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", action="store_true", help="re-record the committed digests")
    parser.add_argument(
        "--record-missing",
        action="store_true",
        help="record only the cases without a committed digest (a task newly added to CASES)",
    )
    parser.add_argument(
        "--tasks", help="comma-separated task names: compare (or record) only their cases"
    )
    args = parser.parse_args(argv)
    cases = select_cases(args.tasks)
    if args.record or args.record_missing:
        if args.record and args.tasks:
            parser.error("--record re-records every case; use --record-missing with --tasks")
        record(cases, only_missing=args.record_missing)
        print(f"wrote {DIGEST_FILE}")
        return 0
    diffs = compare(cases)
    for line in diffs:
        print("DIFFERS", line)
    print("all digests match" if not diffs else f"{len(diffs)} of {len(cases)} differ")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
