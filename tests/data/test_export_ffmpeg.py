"""Without FFmpeg's shared libraries, loading an export says which apt command fixes it.

torchcodec (lerobot's video decoder) is made to fail on import by a meta-path finder, so neither
lerobot nor torch is needed.
"""

import importlib.abc
import importlib.util
import re
import sys
from pathlib import Path

import pytest

from bicoord_drake.data import export

ROOT = Path(__file__).resolve().parents[2]
#: The tail of torchcodec 0.14's error on a machine without FFmpeg (trimmed).
TORCHCODEC_ERROR = (
    "Could not load libtorchcodec. Likely causes:\n"
    "  1. FFmpeg is not properly installed in your environment. ...\n"
    "[start of libtorchcodec loading traceback]\n"
    "FFmpeg version 5:\n"
    "OSError: libavutil.so.57: cannot open shared object file: No such file or directory\n"
    "[end of libtorchcodec loading traceback]."
)


class FailingTorchcodec(importlib.abc.MetaPathFinder):
    """Importing torchcodec (or a submodule) raises `error`, as its library loader does."""

    def __init__(self, error: Exception) -> None:
        self.error = error

    def find_spec(self, name, path, target=None):
        if name.split(".")[0] == "torchcodec":
            raise self.error
        return None


@pytest.fixture
def torchcodec_fails(monkeypatch):
    def install(error: Exception, ffmpeg_installed: bool = False) -> None:
        for name in [m for m in sys.modules if m.split(".")[0] == "torchcodec"]:
            monkeypatch.delitem(sys.modules, name)
        monkeypatch.setattr(sys, "meta_path", [FailingTorchcodec(error), *sys.meta_path])
        monkeypatch.setattr(export, "ffmpeg_installed", lambda: ffmpeg_installed)

    return install


@pytest.mark.parametrize(
    "error",
    [
        RuntimeError(TORCHCODEC_ERROR),
        OSError("libavutil.so.57: cannot open shared object file: No such file or directory"),
    ],
)
def test_missing_ffmpeg_names_the_apt_command(torchcodec_fails, error):
    torchcodec_fails(error)
    with pytest.raises(export.MissingFFmpegError) as info:
        export.require_video_decoder()
    message = str(info.value)
    assert (
        "sudo apt-get install -y libavcodec59 libavformat59 libavutil57 libswscale6 "
        "libswresample4 libavdevice59 libavfilter8" in message
    )
    assert "torchcodec" in message and "videos" in message  # what the libraries are for
    assert info.value.__cause__ is error  # torchcodec's own report stays in the traceback


def test_loading_an_export_checks_the_decoder_first(torchcodec_fails, monkeypatch, tmp_path):
    torchcodec_fails(RuntimeError(TORCHCODEC_ERROR))
    monkeypatch.setattr(export, "require_lerobot", lambda: None)
    with pytest.raises(export.MissingFFmpegError):
        export.load_lerobot(tmp_path, "bicoord_drake/demo_task")


@pytest.mark.parametrize(
    ("error", "ffmpeg_installed"),
    [
        (RuntimeError(TORCHCODEC_ERROR), True),  # FFmpeg is there: another cause
        (RuntimeError("torchcodec: undefined symbol in libtorchcodec_core5.so"), False),
        (OSError("disk on fire"), False),
    ],
)
def test_other_torchcodec_failures_pass_through(torchcodec_fails, error, ffmpeg_installed):
    torchcodec_fails(error, ffmpeg_installed)
    with pytest.raises(type(error)) as info:
        export.require_video_decoder()
    assert info.value is error


def test_the_packages_are_the_ones_ci_installs():
    ci = (ROOT / ".ci/run").read_text()
    installed = set(re.findall(r"\blib(?:av|sw)\w+\d+\b", ci))
    assert installed == set(export.FFMPEG_DEBIAN_PACKAGES)


@pytest.mark.skipif(
    importlib.util.find_spec("torchcodec") is None, reason="torchcodec is not installed"
)
def test_the_real_torchcodec_is_diagnosed_as_this_machine_is():
    """With FFmpeg installed the decoder loads; without, the real torchcodec error is caught."""
    if export.ffmpeg_installed():
        export.require_video_decoder()
    else:
        with pytest.raises(export.MissingFFmpegError):
            export.require_video_decoder()
