"""Policies for the tests, loaded by spec (``tests.policies.dummy:<name>``)."""

import numpy as np


class Hold:
    """Holds the first observed joint state; remembers its instructions."""

    def __init__(self, scale: float = 1.0):
        self.scale = scale
        self.instructions = []
        self.target = None

    def reset(self, instruction):
        self.instructions.append(instruction)
        self.target = None

    def act(self, obs):
        if self.target is None:
            self.target = np.asarray(obs["joint_state"], dtype=float)
        return self.target


class Raises:
    """Raises on its third action."""

    def reset(self, instruction):
        self.calls = 0

    def act(self, obs):
        self.calls += 1
        if self.calls == 3:
            raise RuntimeError("policy bug on purpose")
        return obs["joint_state"]


class ReturnsNan:
    def reset(self, instruction):
        pass

    def act(self, obs):
        a = np.array(obs["joint_state"], dtype=float)
        a[4] = np.nan
        return a


class WrongShape:
    def reset(self, instruction):
        pass

    def act(self, obs):
        return np.zeros(13)


def act_function(obs):
    """A bare function policy."""
    return obs["joint_state"]


def make_hold():
    """A zero-argument factory."""
    return Hold(scale=2.0)


class BrokenConstructor:
    def __init__(self):
        raise OSError("weights not found")

    def act(self, obs):
        return obs["joint_state"]


NOT_A_POLICY = 42


class Spy:
    """Holds still and records, at every bind, what the environment was built with."""

    bound: list[dict] = []

    def bind(self, env):
        Spy.bound.append(
            {"setup": env.setup, "scene": env.scene, "station": env.sim.station.config}
        )

    def reset(self, instruction):
        pass

    def act(self, obs):
        return obs["joint_state"]


class OutOfLimits:
    """Holds the first observed joint state, but its 1st and 3rd actions send the left waist
    to 10 rad (past its limit) and its 3rd also opens the right gripper to 1.25 (past 1)."""

    def reset(self, instruction):
        self.target = None
        self.step = 0

    def act(self, obs):
        if self.target is None:
            self.target = np.asarray(obs["joint_state"], dtype=float)
        self.step += 1
        a = self.target.copy()
        if self.step in (1, 3):
            a[0] = 10.0
        if self.step == 3:
            a[13] = 1.25
        return a
