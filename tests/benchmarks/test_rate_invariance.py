"""benchmarks/rate_invariance.py: a seed whose process dies is a failed row, not the end."""

import importlib.util
import os
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "rate_invariance.py"


@pytest.fixture(scope="module")
def ri():
    spec = importlib.util.spec_from_file_location("rate_invariance", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["rate_invariance"] = module  # dataclasses resolve their module by name
    spec.loader.exec_module(module)
    return module


def test_a_native_crash_is_a_failed_row_and_the_next_seed_runs(ri, monkeypatch):
    def run_one(task, rate, seed):
        if seed == 1:
            os.abort()  # as Drake's "Unreachable code was reached" abort does
        return ri.Run(task, rate, seed, True, "", 10, 0.5, 0.0)

    monkeypatch.setattr(ri, "run_one", run_one)
    died = ri.run_isolated(("jigsaw", 50.0, 1))
    assert not died.kept and "exit code -6" in died.reason
    kept = ri.run_isolated(("jigsaw", 50.0, 2))
    assert kept.kept and kept.steps == 10
