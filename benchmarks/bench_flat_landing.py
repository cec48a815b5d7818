"""A compliant block landing flat on a flat face, under the station's contact settings.

    python benchmarks/bench_flat_landing.py [--out benchmarks/bench_flat_landing.md]

clean_table's blocks were thrown out of the bin at 2-8 m/s, spinning at 100-150 rad/s, when
they landed flat on its rigid floor at under 1 m/s. This reproduces it without the robot: a
4.5 cm, 60 g compliant-hydroelastic box (the station's object settings: 1e6 Pa, 1 cm mesh,
dissipation 3 s/m, friction 0.9) is let go level, still, at heights spread over one plant
step's travel (where it meets the floor within a step decides the outcome) onto a floor slab,
and the highest upward speed after it lands is recorded. Variants change one setting of the
station's plant (SAP, 1/120 s, near-rigid threshold 0, hydroelastic margin 0.1 mm) or of the
floor. A landing that bounces faster than it arrived gained energy.
"""

from __future__ import annotations

import argparse
import platform
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.all import (
    AddCompliantHydroelasticProperties,
    AddContactMaterial,
    AddMultibodyPlantSceneGraph,
    AddRigidHydroelasticProperties,
    Box,
    ContactModel,
    CoulombFriction,
    DiagramBuilder,
    DiscreteContactApproximation,
    ProximityProperties,
    RigidTransform,
    Simulator,
    SpatialInertia,
    UnitInertia,
)

SIZE, MASS = 0.045, 0.06
#: Heights (m) of the block's underside above the floor when let go: 2-5 cm (0.63-0.99 m/s).
HEIGHTS = tuple(np.round(np.linspace(0.02, 0.05, 31), 4))
#: Releases just above the floor, 0.2-3 mm (0.06-0.24 m/s): a gripper letting go of an object
#: it holds a fraction of a millimetre above the table (handover_block_with_bowls' bowls).
LOW_HEIGHTS = tuple(np.round(np.linspace(0.0002, 0.003, 15), 5))


@dataclass(frozen=True)
class Variant:
    name: str
    approximation: str = "sap"
    time_step: float = 1 / 120
    margin: float = 1e-4
    near_rigid: float = 0.0
    floor_modulus: float | None = None  # None: rigid floor
    block_margin: float | None = None  # None: `margin` (SceneObject.contact_margin's case)


VARIANTS = (
    Variant("station (SAP, 1/120 s, margin 0.1 mm), rigid floor"),
    Variant("compliant floor, 1e6 Pa (clean_table's bin)", floor_modulus=1e6),
    Variant("compliant floor, 5e6 Pa", floor_modulus=5e6),
    Variant("SAP near-rigid threshold 1.0", near_rigid=1.0),
    Variant("margin 3 mm", margin=3e-3),
    Variant("margin 5 mm", margin=5e-3),
    Variant("margin 5 mm on the block only, floor 0.1 mm", block_margin=5e-3),
    Variant("1/240 s", time_step=1 / 240),
    Variant("1/480 s", time_step=1 / 480),
    Variant("similar approximation", approximation="similar"),
    Variant("lagged approximation", approximation="lagged"),
)
APPROXIMATIONS = {
    "sap": DiscreteContactApproximation.kSap,
    "similar": DiscreteContactApproximation.kSimilar,
    "lagged": DiscreteContactApproximation.kLagged,
}


def _props(modulus: float | None, margin: float) -> ProximityProperties:
    props = ProximityProperties()
    if modulus is None:
        AddRigidHydroelasticProperties(0.01, props)
    else:
        AddCompliantHydroelasticProperties(0.01, modulus, props)
    AddContactMaterial(dissipation=3.0, friction=CoulombFriction(0.9, 0.9), properties=props)
    props.AddProperty("hydroelastic", "margin", margin)
    return props


def landing(variant: Variant, height: float) -> tuple[float, float, float]:
    """(speed at impact, highest upward speed after it, highest spin) in m/s, rad/s."""
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, time_step=variant.time_step)
    plant.set_discrete_contact_approximation(APPROXIMATIONS[variant.approximation])
    plant.set_sap_near_rigid_threshold(variant.near_rigid)
    plant.set_contact_model(ContactModel.kHydroelasticWithFallback)
    floor = _props(variant.floor_modulus, variant.margin)
    plant.RegisterCollisionGeometry(
        plant.world_body(), RigidTransform([0, 0, -0.01]), Box(0.4, 0.4, 0.02), "floor", floor
    )
    block = plant.AddRigidBody(
        "block", SpatialInertia(MASS, np.zeros(3), UnitInertia.SolidBox(SIZE, SIZE, SIZE))
    )
    plant.RegisterCollisionGeometry(
        block,
        RigidTransform(),
        Box(SIZE, SIZE, SIZE),
        "block",
        _props(1e6, variant.margin if variant.block_margin is None else variant.block_margin),
    )
    plant.Finalize()
    simulator = Simulator(builder.Build())
    context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    plant.SetFreeBodyPose(context, block, RigidTransform([0, 0, SIZE / 2 + height]))
    up, spin = 0.0, 0.0
    for k in range(1, round(0.8 / variant.time_step)):
        simulator.AdvanceTo(k * variant.time_step)
        V = block.EvalSpatialVelocityInWorld(context)
        up = max(up, float(V.translational()[2]))
        spin = max(spin, float(np.linalg.norm(V.rotational())))
    return float(np.sqrt(2 * 9.81 * height)), up, spin


def drops(variant: Variant, heights: Sequence[float]) -> tuple[np.ndarray, int, float]:
    """`variant` dropped from each of `heights`: the upward speeds after landing (m/s), how
    many came back up faster than they arrived (gained energy), the largest spin (rad/s)."""
    results = [landing(variant, h) for h in heights]
    ups = np.array([up for _, up, _ in results])
    gained = int(np.sum(ups > np.array([v for v, _, _ in results])))
    return ups, gained, max(s for _, _, s in results)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, help="write the table here (markdown)")
    args = parser.parse_args()
    rows = []
    for variant in VARIANTS:
        t0 = time.perf_counter()
        ups, gained, spin = drops(variant, HEIGHTS)
        low_ups, low_gained, _ = drops(variant, LOW_HEIGHTS)
        rows.append(
            f"| {variant.name} | {gained}/{len(HEIGHTS)} | {int(np.sum(ups > 1.0))} | "
            f"{ups.max():.2f} | {spin:.0f} | "
            f"{low_gained}/{len(LOW_HEIGHTS)} | {low_ups.max():.2f} | "
            f"{time.perf_counter() - t0:.1f} |"
        )
        print(rows[-1], flush=True)
    text = "\n".join(
        [
            "# A compliant block landing flat (bench_flat_landing.py)",
            "",
            f"{time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC, {platform.machine()}, "
            f"Python {platform.python_version()}; `python benchmarks/bench_flat_landing.py`. "
            f"A 4.5 cm, 60 g compliant block let go level and still {HEIGHTS[0] * 100:.0f}-"
            f"{HEIGHTS[-1] * 100:.0f} cm above a floor slab ({len(HEIGHTS)} heights, "
            "0.63-0.99 m/s at impact); per variant: landings that bounced faster than they "
            "arrived, landings thrown up faster than 1 m/s, the fastest upward speed and spin "
            "after landing; then the same for releases just above the floor "
            f"({LOW_HEIGHTS[0] * 1000:.1f}-{LOW_HEIGHTS[-1] * 1000:.0f} mm, "
            f"{len(LOW_HEIGHTS)} heights: a grip letting go of a held object); wall time of both.",
            "",
            "| variant | gained energy | up > 1 m/s | max up, m/s | max spin, rad/s | "
            "low release: gained energy | low release: max up, m/s | wall, s |",
            "|---|---:|---:|---:|---:|---:|---:|---:|",
            *rows,
            "",
        ]
    )
    if args.out:
        args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
