"""Every robot starts its TCPs as far apart as the reference robot's (PRODUCT.md, d0)."""

import numpy as np
import pytest

from bicoord_drake.config import StationConfig
from bicoord_drake.metrics.report import REFERENCE_D0
from bicoord_drake.models.robots import EMBODIMENTS, get_embodiment
from bicoord_drake.models.scene import Scene
from bicoord_drake.planning.model import PlanningModel
from bicoord_drake.sim.simulation import Simulation
from bicoord_drake.sim.station import build_station


def _embodiment(name):
    return get_embodiment(name)


@pytest.mark.parametrize("name", sorted(EMBODIMENTS))
def test_home_tcps_start_at_the_reference_distance(name):
    embodiment = _embodiment(name)
    model = PlanningModel(Scene(), embodiment)
    left, right = (model.tcp_pose(model.home, side).translation() for side in ("left", "right"))
    # within 2 cm of the reference (PRODUCT.md: a robot whose home differs by more gets a spread)
    assert abs(np.linalg.norm(left - right) - REFERENCE_D0["BiCoord"]) < 0.02
    # mirror images about the centre plane x = 0 (the Panda's flange offset: a few micrometres)
    assert left[0] == pytest.approx(-right[0], abs=1e-4)
    assert left[1:] == pytest.approx(right[1:], abs=1e-4)


def test_the_viperx_waists_turn_outward_to_the_reference_distance():
    embodiment = _embodiment("aloha_viperx")
    model = PlanningModel(Scene(), embodiment)
    left, right = (model.tcp_pose(model.home, side).translation() for side in ("left", "right"))
    assert np.linalg.norm(left - right) == pytest.approx(0.606, abs=1e-3)
    assert left[0] < embodiment.left_base.xyz[0] and right[0] > embodiment.right_base.xyz[0]
    action = embodiment.home_action()
    n = embodiment.num_arm_joints
    assert action[0] == pytest.approx(embodiment.home_spread)
    assert action[n + 1] == pytest.approx(-embodiment.home_spread)
    assert np.array_equal(action[1:n], action[n + 2 : 2 * n + 1])


def test_a_spread_beyond_the_joint_limits_is_refused():
    embodiment = _embodiment("aloha_viperx")
    lower = embodiment.arm.lower[0]
    data = embodiment.model_dump()
    data["home"] = (float(lower) + 0.05, *data["home"][1:])
    with pytest.raises(ValueError, match="right arm's home"):
        type(embodiment)(**data)


def test_the_simulated_robot_starts_at_its_home():
    sim = Simulation(build_station(Scene(), StationConfig(render=False)))
    sim.reset()
    home = sim.station.embodiment.home_action()
    assert sim.joint_state() == pytest.approx(home, abs=1e-6)
    left, right = (sim.tcp_pose(side)[:3] for side in ("left", "right"))
    assert np.linalg.norm(left - right) == pytest.approx(0.606, abs=1e-3)
