"""load_policy: built-ins, module:name specs, and clear errors for bad specs."""

import numpy as np
import pytest

from bicoord_drake.policies import (
    ExpertPolicy,
    FunctionPolicy,
    NoopPolicy,
    PolicyLoadError,
    ReplayPolicy,
    load_policy,
)
from tests.policies import dummy


@pytest.mark.parametrize(
    "spec,cls", [("replay", ReplayPolicy), ("expert", ExpertPolicy), ("noop", NoopPolicy)]
)
def test_builtins(spec, cls):
    assert isinstance(load_policy(spec), cls)


def test_class_is_instantiated_with_kwargs():
    policy = load_policy("tests.policies.dummy:Hold", scale=3.0)
    assert isinstance(policy, dummy.Hold) and policy.scale == 3.0


def test_function_becomes_act_and_factory_is_called():
    fn = load_policy("tests.policies.dummy:act_function")
    assert isinstance(fn, FunctionPolicy)
    fn.reset("anything")
    obs = {"joint_state": np.arange(14.0)}
    assert np.array_equal(fn.act(obs), obs["joint_state"])
    made = load_policy("tests.policies.dummy:make_hold")
    assert isinstance(made, dummy.Hold) and made.scale == 2.0


@pytest.mark.parametrize(
    "spec,words",
    [
        ("no_such_pkg.mod:Policy", ["cannot import module", "no_such_pkg"]),
        ("tests.policies.dummy:Missing", ["has no attribute", "Missing"]),
        ("tests.policies.dummy:NOT_A_POLICY", ["int", "not a class"]),
        ("tests.policies.dummy:BrokenConstructor", ["constructing", "weights not found"]),
        ("just words", ["must be a built-in", "package.module:name"]),
        ("module_only", ["must be a built-in"]),
    ],
)
def test_bad_specs_name_the_problem(spec, words):
    with pytest.raises(PolicyLoadError) as err:
        load_policy(spec)
    for word in words:
        assert word in str(err.value)


def test_noop_unbound_holds_the_first_joint_state():
    policy = NoopPolicy()
    policy.reset("x")
    first = policy.act({"joint_state": np.ones(14)})
    again = policy.act({"joint_state": np.zeros(14)})
    assert np.array_equal(first, np.ones(14)) and np.array_equal(again, np.ones(14))


def test_load_policy_for_passes_the_action_size_only_to_sized_policies():
    from bicoord_drake.policies import SIZED_PREFIXES, action_size_of, load_policy_for

    assert isinstance(load_policy_for("noop", action_size=14), NoopPolicy)
    held = load_policy_for("tests.policies.dummy:Hold", action_size=14, scale=2.0)
    assert held.scale == 2.0
    assert SIZED_PREFIXES == ("lerobot:", "openpi:", "lerobot-dataset:")
    assert action_size_of("aloha_viperx") == 14 and action_size_of("aloha_viperx", "endpose") == 16
    with pytest.raises(ValueError, match="action_mode must be"):
        action_size_of("aloha_viperx", "torque")


def test_close_policy_and_env_action_size():
    from types import SimpleNamespace

    from bicoord_drake.policies import close_policy, env_action_size

    closed = []
    close_policy(SimpleNamespace(close=lambda: closed.append(True)))
    close_policy(NoopPolicy())  # no close(): nothing to do
    assert closed == [True]
    assert env_action_size(SimpleNamespace(action_size=14)) == 14
    gym_like = SimpleNamespace(unwrapped=SimpleNamespace(action_space=SimpleNamespace(shape=(16,))))
    assert env_action_size(gym_like) == 16
    assert env_action_size(object()) is None
