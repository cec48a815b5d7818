"""A diverging simulation stops with a PhysicsDivergedError that names the body, and the
rollout reports it as a physics failure (not as the policy's invalid action)."""

import numpy as np
import pytest
from pydrake.all import SpatialVelocity

from bicoord_drake.config import StationConfig
from bicoord_drake.models.geometry import Pose
from bicoord_drake.models.objects import CylinderShape, SceneObject
from bicoord_drake.models.scene import Scene
from bicoord_drake.sim.simulation import PhysicsDivergedError, Simulation
from bicoord_drake.sim.station import build_station


def spinning_rod(spin: float) -> Simulation:
    """A 36 cm x 4 cm rod (the balance_roller roller's shape and mass) falling freely far from
    the arms, spinning at `spin` rad/s about its long axis with a 5 % wobble. At the default
    plant step such a spin is unstable: the explicit gyroscopic term feeds the wobble
    (free-flight thresholds measured on a bare plant: about 25 rad/s at 1/120 s, 40 at 1/240 s,
    55 at 1/480 s)."""
    rod = SceneObject(
        name="rod",
        shape=CylinderShape(radius=0.019, length=0.36),
        mass=0.185,
        pose=Pose(xyz=(0.0, 1.5, 2.5)),  # beyond the table: nothing below
    )
    sim = Simulation(build_station(Scene(name="rod", objects=(rod,)), StationConfig(render=False)))
    plant = sim.station.plant
    body = plant.GetBodyByName("rod")
    w = np.array([0.05, 0.02, 1.0]) * spin  # along the rod's axis (object z)
    plant.SetFreeBodySpatialVelocity(sim.plant_context, body, SpatialVelocity(w, np.zeros(3)))
    return sim


def test_a_diverging_step_raises_and_names_the_spinning_body():
    sim = spinning_rod(80.0)
    home = sim.station.embodiment.home_action()
    with pytest.raises(PhysicsDivergedError, match=r"'rod' spun at \d+ rad/s"):
        for _ in range(15):  # 1 s (it diverges within 12 steps, before reaching the floor)
            sim.step(home)


def test_a_slow_spin_stays_finite():
    sim = spinning_rod(10.0)
    home = sim.station.embodiment.home_action()
    for _ in range(8):  # in the air all along
        sim.step(home)
    w = sim.station.plant.GetBodyByName("rod").EvalSpatialVelocityInWorld(sim.plant_context)
    assert np.linalg.norm(w.rotational()) == pytest.approx(10.0 * np.sqrt(1.0029), rel=0.02)


def test_a_flailing_policy_stream_replays_without_divergence():
    """A Diffusion Policy's recorded actions (extract_bottom_block_to_top, seed 100010, as the
    servos follow them: benchmarks/data/divergence) drive links into links and into the table.
    Under the default physics the replay stays finite and no cube is thrown faster than a few
    m/s; under the "lagged" approximation the same stream threw cubes at 150+ m/s and diverged
    at control step 92 (benchmarks/bench_divergence.py)."""
    from pathlib import Path

    from bicoord_drake.env import Env
    from bicoord_drake.episode_setup import EpisodeSetup

    root = Path(__file__).resolve().parents[2]
    actions = np.load(root / "benchmarks/data/divergence/extract_bottom_block_to_top__100010.npy")
    seed = 100010
    env = Env(
        EpisodeSetup(
            task="extract_bottom_block_to_top", seed=seed, station=StationConfig(render=False)
        )
    )
    env.reset(seed)
    plant, context = env.sim.station.plant, env.sim.plant_context
    cubes = [plant.get_body(i) for i in plant.GetFloatingBaseBodies()]
    peak = 0.0
    for action in actions:  # raises PhysicsDivergedError if the state turns non-finite
        env.step(action)
        for cube in cubes:
            v = cube.EvalSpatialVelocityInWorld(context).translational()
            peak = max(peak, float(np.linalg.norm(v)))
    assert peak < 10.0
