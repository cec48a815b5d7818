"""scripts/render.py: writes one image per camera and a contact sheet; bad input is one line."""

import subprocess
import sys
from pathlib import Path

import numpy as np
from PIL import Image

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "render.py"


def run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True)


def test_render_writes_three_views_and_a_contact_sheet(tmp_path):
    result = run("--scene", "cubes", "--out", str(tmp_path), "--resolution", "160x120")
    assert result.returncode == 0, result.stderr
    for name in ("head_camera", "left_camera", "right_camera"):
        img = np.asarray(Image.open(tmp_path / f"{name}.png"))
        assert img.shape == (120, 160, 3) and img.std() > 10
    assert Image.open(tmp_path / "contact_sheet.png").size[0] == 3 * 160
    assert not list(tmp_path.glob("*.tmp"))


def test_bad_arguments_give_one_line_errors():
    for args, word in [
        (("--scene", "kitchen"), "cubes"),
        (("--resolution", "big"), "WIDTHxHEIGHT"),
        (("--resolution", "8x8"), "range"),
        (("--pose", "dance"), "reach"),
    ]:
        result = run(*args)
        assert result.returncode == 2
        assert "Traceback" not in result.stderr
        assert len(result.stderr.strip().splitlines()) == 1 and word in result.stderr
