#!/usr/bin/env python
"""Export generated episodes to a LeRobot dataset.

Examples:
    python scripts/export.py data --to lerobot --out lerobot/jigsaw              # codebase v3.0
    python scripts/export.py data/jigsaw --to lerobot --out lr21 --codebase v2.1
    python scripts/export.py data --to lerobot --out lr --dtype float64 --check
    python scripts/export.py data --to lerobot --out lr_state --environment-state --no-images
    python scripts/export.py data/jigsaw --to lerobot --out lr50 --max-episodes 50  # first 50

DATA_DIR holds episode files (searched recursively for *.hdf5), e.g. the --out of
scripts/generate.py, all of one robot. Features: observation.state and action (the robot's
joints and openings: 14 each for the ViperX pair), observation.endpose (both TCP poses),
stage_index per frame, the three cameras as videos, the instruction as the task.
--environment-state adds observation.environment_state, the task objects' poses (xyz + wxyz per
object, in the scene's order; names in meta/info.json), the privileged state small policies
train on; --no-images leaves the cameras out (needed for episodes generated with --no-render).
When an episode was generated with --disturb, every frame gets `disturbed` (int8: 1 from a
disturbance's step to the end of its recovery row, else 0; 0 throughout clean episodes).
v3.0 is written by lerobot's LeRobotDataset; v2.1 in lerobot's v2.1 layout. Needs the [lerobot]
extra (see the README). --check loads the result with LeRobotDataset (a v2.1 export after
converting it with lerobot's converter in a temporary directory) and compares it with the source.
"""

from __future__ import annotations

import argparse
import sys
import tempfile


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[1],
        epilog=__doc__.split("\n", 2)[2],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("paths", nargs="+", metavar="DATA_DIR", help="episode files or directories")
    parser.add_argument("--to", required=True, choices=["lerobot"], help="target format")
    parser.add_argument("--out", required=True, help="new dataset directory (must not exist)")
    parser.add_argument(
        "--codebase", default="v3.0", choices=["v3.0", "v2.1"], help="LeRobot codebase version"
    )
    parser.add_argument("--repo-id", help="dataset repo id (default: bicoord_drake/<task>)")
    parser.add_argument(
        "--dtype",
        default="float32",
        choices=["float32", "float64"],
        help="stored states, actions and poses (float64: bit-exact columns; default float32)",
    )
    parser.add_argument(
        "--vcodec", default="libsvtav1", help="video codec (lerobot's default libsvtav1)"
    )
    parser.add_argument(
        "--environment-state",
        action="store_true",
        help="add observation.environment_state: the task objects' poses (privileged state)",
    )
    parser.add_argument(
        "--no-images",
        dest="images",
        action="store_false",
        help="leave the camera videos out (a state-only dataset)",
    )
    parser.add_argument(
        "--max-episodes",
        type=int,
        metavar="N",
        help="export only the first N episode files (natural order: the first N seeds of a "
        "generate.py directory); fewer is an error",
    )
    parser.add_argument(
        "--check", action="store_true", help="load the export with lerobot and compare"
    )
    args = parser.parse_args(argv)

    from bicoord_drake.data import export

    if args.check:
        try:  # fail before a long export when the check could not decode its videos
            export.require_video_decoder()
        except (ImportError, export.MissingFFmpegError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 1
    try:
        result = export.export_lerobot(
            args.paths,
            args.out,
            repo_id=args.repo_id,
            codebase=args.codebase,
            dtype=args.dtype,
            vcodec=args.vcodec,
            images=args.images,
            environment_state=args.environment_state,
            max_episodes=args.max_episodes,
        )
    except (ImportError, FileExistsError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    print(
        f"wrote {result.root} (LeRobot {result.codebase}, repo_id {result.repo_id}): "
        f"{result.episodes} episodes, {result.frames} frames"
    )
    if not args.check:
        return 0
    with tempfile.TemporaryDirectory() as work:
        root = result.root
        if result.codebase == "v2.1":
            root = export.convert_v21_to_v30(result.root, result.repo_id, work)
        dataset = export.load_lerobot(root, result.repo_id)
        episodes = export.load_episodes(
            result.sources, images=args.images, environment_state=args.environment_state
        )
        check = export.check_export(dataset, episodes)
    print(
        f"check: frame counts {'match' if all(a == b for a, b in check.frame_counts) else 'DIFFER'}"
        f"; exact: {', '.join(k for k, v in check.numeric_exact.items() if v) or 'none'}"
        f"; images: mean |error| {check.image_mean_abs_error:.2f} levels over "
        f"{check.images_compared} frames (worst {check.image_max_mean_abs_error:.2f})"
    )
    return 0 if check.ok else 1


if __name__ == "__main__":
    sys.exit(main())
