"""Free-flight stability of a thin body spinning about its axis, per plant time step.

    python benchmarks/bench_spin_stability.py

A roller-like rod (balance_roller's: 0.185 kg, inertia 2.013e-3 / 2.013e-3 / 3.34e-5 kg m^2)
floats without gravity under Drake's discrete plant ("lagged" approximation) with a spin about
its axis plus a small wobble (5 % and 2 % of the spin about the transverse axes), or a spin
about a transverse axis. Prints the growth of |w| over one simulated second: 1.0 is exact
(torque-free motion keeps |w| for a symmetric body), large numbers mean the explicit
gyroscopic term diverges. Results: bench_expert_physics.md, "Thin bodies spinning".
"""

from __future__ import annotations

import numpy as np
from pydrake.all import (
    AddMultibodyPlantSceneGraph,
    DiagramBuilder,
    DiscreteContactApproximation,
    RotationalInertia,
    Simulator,
    SpatialInertia,
    SpatialVelocity,
)

MASS = 0.185
INERTIA = (2.013e-3, 2.013e-3, 3.34e-5)  # about x, y (transverse) and z (the axis)
SPINS = (10.0, 20.0, 30.0, 45.0, 60.0, 80.0)
STEPS = (1 / 120, 1 / 240, 1 / 480)


def growth(time_step: float, w0: np.ndarray, seconds: float = 1.0) -> float:
    """max |w| / |w0| over `seconds` of free flight (inf once it passes 1e6 times)."""
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, time_step=time_step)
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kLagged)
    inertia = SpatialInertia.MakeFromCentralInertia(MASS, np.zeros(3), RotationalInertia(*INERTIA))
    body = plant.AddRigidBody("rod", inertia)
    plant.mutable_gravity_field().set_gravity_vector(np.zeros(3))
    plant.Finalize()
    simulator = Simulator(builder.Build())
    context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    plant.SetFreeBodySpatialVelocity(context, body, SpatialVelocity(w0, np.zeros(3)))
    peak = 0.0
    for k in range(1, round(seconds / time_step) + 1):
        try:
            simulator.AdvanceTo(k * time_step)
        except RuntimeError:
            return float("inf")
        peak = max(
            peak, float(np.linalg.norm(body.EvalSpatialVelocityInWorld(context).rotational()))
        )
        if not np.isfinite(peak) or peak > 1e6 * np.linalg.norm(w0):
            return float("inf")
    return peak / float(np.linalg.norm(w0))


def main() -> None:
    header = " | ".join(f"{w:.0f} rad/s" for w in SPINS)
    for name, direction in (("about the axis", (0.05, 0.02, 1.0)), ("tumbling", (1.0, 0.0, 0.05))):
        print(f"\n{name}\n| plant step | {header} |\n|---|" + "---:|" * len(SPINS))
        for dt in STEPS:
            cells = " | ".join(f"{growth(dt, w * np.array(direction)):.3g}" for w in SPINS)
            print(f"| 1/{round(1 / dt)} s | {cells} |")


if __name__ == "__main__":
    main()
