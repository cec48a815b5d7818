"""The closed-loop physics-lever benchmark: its table and its guard on variant names."""

import pytest

from bicoord_drake.config import StationConfig
from tests.runner.benchmark_scripts import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bench_expert_physics")


def test_every_variant_is_a_valid_station_config(bench):
    for fields in bench.VARIANTS.values():
        StationConfig(render=False, **fields)  # a typo in a field name fails here
    before = StationConfig(render=False, **bench.VARIANTS["sap (today)"])
    assert (before.contact_approximation, before.time_step) == ("sap", 1 / 300)
    assert before.hydroelastic_margin == 0


def test_table_gives_kept_speed_ratio_and_failures(bench):
    def rec(seed, ok, frames=150, wall=10.0, reason=None):
        return {
            "seed": seed,
            "success": ok,
            "reason": reason,
            "frames": frames,
            "sim_seconds": frames / 15,
            "physics_wall": wall,
        }

    today = bench._summary([rec(0, True), rec(1, True)])
    lagged = bench._summary([rec(0, True, wall=5.0), rec(1, False, reason="pick_failed")])
    assert (today["kept"], today["tried"]) == (2, 2) and today["speed"] == pytest.approx(1.0)
    assert lagged["speed"] == pytest.approx(2.0) and lagged["reasons"] == ["1: pick_failed"]
    text = bench.render_markdown(
        {"jigsaw": {"sap (today)": today, "lagged": lagged}}, ["sap (today)", "lagged"], [0, 1], ""
    )
    assert "| jigsaw | 2/2, 1.00 (1.00x) | 1/2, 2.00 (2.00x) |" in text
    assert "| median ratio | 1.00x | 2.00x |" in text
    assert "- jigsaw, lagged: seed 1: pick_failed" in text


def test_unknown_variant_is_refused_with_the_known_ones(bench, capsys):
    with pytest.raises(SystemExit):
        bench.main(["--variants", "sap (today),fast"])
    assert "known:" in capsys.readouterr().err
