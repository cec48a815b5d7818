"""(slow) The experts of the tasks in CASES send bit-identical actions to the committed digests.

See ``tests/tasks/expert_digests.py`` for what is compared and how to re-record after an
intended plan change.
"""

import pytest

from tests.tasks.expert_digests import (
    CASES,
    DIGEST_FILE,
    case_key,
    compare,
    load_digests,
    select_cases,
)


def test_every_case_has_a_committed_digest():
    committed = load_digests()
    assert {case_key(t, s) for t, s in CASES} <= set(committed), f"re-record {DIGEST_FILE}"
    for entry in committed.values():
        assert entry["steps"] > 0 and len(entry["sha256"]) == 64


def test_select_cases_keeps_the_named_tasks_and_rejects_unknown_ones():
    assert select_cases(None) == CASES
    assert select_cases("jigsaw, cook") == tuple(c for c in CASES if c[0] in ("jigsaw", "cook"))
    with pytest.raises(ValueError, match="no digest cases for \\['jigsw'\\].*jigsaw"):
        select_cases("jigsw")


@pytest.mark.slow
def test_expert_actions_match_the_committed_digests():
    diffs = compare()
    assert not diffs, "expert plans changed:\n" + "\n".join(diffs)
