#!/usr/bin/env python
"""Render the simulated cell from the head and both wrist cameras.

Examples:
    python scripts/render.py                                  # demo scene -> renders/
    python scripts/render.py --scene cubes --out /tmp/look --resolution 640x480
    python scripts/render.py --pose home --depth

Writes head_camera.png, left_camera.png, right_camera.png (and *_depth.png in millimetres with
--depth) plus contact_sheet.png into --out.
"""

from __future__ import annotations

import argparse
import sys
import time

from pydantic import ValidationError


def main(argv: list[str] | None = None) -> int:
    from bicoord_drake.models.scene import DEMO_SCENES
    from bicoord_drake.sim.snapshot import ARM_POSES

    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split("\n", 2)[2],
    )
    parser.add_argument(
        "--scene",
        default="demo",
        help=f"scene to build, one of: {', '.join(DEMO_SCENES)} (default: demo)",
    )
    parser.add_argument("--out", default="renders", help="output directory (default: renders)")
    parser.add_argument("--resolution", default="320x240", help="WIDTHxHEIGHT (default 320x240)")
    parser.add_argument(
        "--pose", default="reach", help=f"arm pose, one of: {', '.join(ARM_POSES)} (default: reach)"
    )
    parser.add_argument("--depth", action="store_true", help="also write 16-bit depth PNGs (mm)")
    args = parser.parse_args(argv)

    from bicoord_drake.config import (
        CameraConfig,
        StationConfig,
        parse_resolution,
        validation_message,
    )
    from bicoord_drake.models.scene import demo_scene
    from bicoord_drake.sim.snapshot import render_snapshot

    try:
        width, height = parse_resolution(args.resolution)
        scene = demo_scene(args.scene)
        if args.pose not in ARM_POSES:
            raise ValueError(f"unknown pose {args.pose!r}; choose one of: {', '.join(ARM_POSES)}")
        config = StationConfig(cameras=CameraConfig(width=width, height=height, depth=args.depth))
    except (ValueError, ValidationError) as err:
        message = validation_message(err) if isinstance(err, ValidationError) else str(err)
        print(f"error: {message}", file=sys.stderr)
        return 2
    try:
        start = time.perf_counter()
        written = render_snapshot(scene, args.out, config, pose=args.pose)
    except OSError as err:
        print(f"error: cannot write to {args.out}: {err.strerror}", file=sys.stderr)
        return 1
    for name, path in written.items():
        print(f"{name:>20}: {path}")
    print(f"rendered scene {args.scene!r} in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
