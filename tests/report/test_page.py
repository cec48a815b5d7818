"""Dataset report page: parses, embeds decodable images and a video, says what the data says."""

import base64
import html.parser
import importlib.util
import io
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from bicoord_drake.report import build_report, write_report
from bicoord_drake.report.figures import arm_states
from tests.data.synthetic import INSTRUCTION, make_dataset

ROOT = Path(__file__).resolve().parents[2]
VOID = {"meta", "img", "br", "hr", "link", "input", "source"}


class Page(html.parser.HTMLParser):
    """Collects tags, data URIs and text; checks that elements nest properly."""

    def __init__(self) -> None:
        super().__init__()
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.images: list[tuple[str, str]] = []  # (alt, src)
        self.videos: list[dict] = []
        self.text: list[str] = []
        self.tags: list[str] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append(tag)
        if tag == "img":
            self.images.append((a.get("alt", ""), a.get("src", "")))
        if tag == "video":
            self.videos.append(a)
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if tag in VOID:
            return
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes <{self.stack[-1] if self.stack else None}>")
        else:
            self.stack.pop()

    def handle_data(self, data):
        self.text.append(data)


def parse(page: str) -> Page:
    parser = Page()
    parser.feed(page)
    parser.close()
    assert parser.errors == [] and parser.stack == []
    return parser


def decode_data_uri(src: str) -> tuple[str, bytes]:
    match = re.fullmatch(r"data:([\w/+.-]+);base64,([A-Za-z0-9+/=]+)", src)
    assert match, src[:80]
    return match.group(1), base64.b64decode(match.group(2), validate=True)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("data"))


@pytest.fixture(scope="module")
def page(dataset):
    return build_report([dataset], episodes_shown=1)


def test_page_parses_and_every_image_decodes(page):
    parsed = parse(page)
    assert parsed.tags[:2] == ["html", "head"] and "body" in parsed.tags
    alts = [alt for alt, _ in parsed.images]
    # STI curves, length histogram, one timeline, first + last frame of 3 cameras
    assert len(parsed.images) == 3 + 6
    assert "STI curves" in alts and "episode length histogram" in alts
    for alt, src in parsed.images:
        mime, data = decode_data_uri(src)
        with Image.open(io.BytesIO(data)) as img:
            assert img.format == {"image/png": "PNG", "image/jpeg": "JPEG"}[mime], alt
            pixels = np.asarray(img.convert("RGB"))
        assert pixels.std() > 1.0, f"{alt}: blank image"
    assert not re.search(r"(src|href)=\"(?!data:)", page), "the page links to an outside file"


def test_embedded_video_decodes(page):
    av = pytest.importorskip("av")
    (video,) = parse(page).videos
    mime, data = decode_data_uri(video["src"])
    assert mime == "video/mp4"
    with av.open(io.BytesIO(data)) as container:
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    assert len(frames) == 12 and frames[0].shape == (48, 64, 3)
    decode_data_uri(video["poster"])


def test_page_says_what_the_dataset_holds(page):
    text = " ".join(" ".join(parse(page).text).split())
    assert "demo_task 2 / 3 2" in text  # kept / tried from the manifest, episode files
    assert "1× PlanningError: no IK solution" in text
    # Our columns: SMT, SMP, STI per movement test (paper's, jitter-free), d0 and the metres.
    assert (
        "N SMT (paper test) SMT (jitter-free) SMP % (paper test) SMP % (jitter-free) d0 (m) "
        "MRD % MRD (m) ARD % ARD (m) STI % (paper test) STI % (jitter-free) TL SN ON"
    ) in text
    # The paper's rows fill the paper-test columns; BiCoord's d0 (0.606 m) gives its metres.
    assert (
        "paper: BiCoord 329.0 – 92.81 – 0.606 29.59 0.179 55.77 0.338 42.16 – 361.0 4.27 3.66"
    ) in text
    assert "paper: RoboTwin 2.0 60.0 – 26.10 – – 63.83 – 82.37 – 8.13 – 221.0" in text
    assert "paper test = any change of the TCP position" in text
    assert "jitter-free = TCP moved more than 0.0001 m" in text
    # Synthetic episodes start their TCPs 0.6 m apart.
    assert re.search(r"demo_task 2 (\S+ ){4}0\.600 ", text)
    assert "arm working, jitter-free test (share of frames) arm working, paper test" in text
    assert INSTRUCTION in text
    assert "both lift" in text and "put down" in text
    assert "demo_task seed 0 — 12 frames" in text


def test_arm_states_follow_motion_and_grippers():
    still = np.zeros((4, 3))
    moving = np.cumsum(np.full((4, 3), 0.01), axis=0)
    open_, closed = np.ones(4), np.zeros(4)
    assert list(arm_states(moving, still + 1, open_, open_)) == ["neither"] + ["left"] * 3
    assert list(arm_states(still, still + 1, open_, closed)) == ["right"] * 4
    assert list(arm_states(moving, moving + 1, closed, open_))[1:] == ["both"] * 3


def test_write_report_and_errors(dataset, tmp_path):
    out = write_report([dataset], tmp_path / "r" / "report.html", episodes_shown=0)
    assert out.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    with pytest.raises(ValueError, match="no episode files"):
        build_report([tmp_path / "nothing"])


def test_cli(dataset, tmp_path, capsys):
    spec = importlib.util.spec_from_file_location("report_cli", ROOT / "scripts" / "report.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main([str(dataset), "--out", str(tmp_path / "x.html")]) == 0
    assert "wrote" in capsys.readouterr().out
    assert module.main([str(tmp_path / "missing"), "--out", str(tmp_path / "y.html")]) == 1
    assert "no episode files" in capsys.readouterr().err


def chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(chromium() is None, reason="headless Chromium is not installed")
def test_chromium_screenshot_shows_the_page(dataset, tmp_path):
    report = write_report([dataset], tmp_path / "report.html", episodes_shown=1)
    shot = tmp_path / "shot.png"
    run = subprocess.run(
        [
            chromium(),
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--hide-scrollbars",
            "--window-size=1200,2400",
            f"--screenshot={shot}",
            report.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    with Image.open(shot) as img:
        pixels = np.asarray(img.convert("RGB")).astype(int)
    assert pixels.shape == (2400, 1200, 3)
    # rendered content, not a blank page: dark text, the plots' colours, the camera frames
    assert (pixels.sum(axis=2) < 150).mean() > 0.002
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 500


def test_a_recovery_segment_is_shown_on_the_timeline_and_in_the_stage_table(dataset):
    """An episode with a disturbance: its recovery row (``stages/recovery``) is a hatched bar
    of its own below the stages, its frames shaded across them, and a row of the table."""
    from bicoord_drake.data.episode import read_episode
    from bicoord_drake.report import figures
    from bicoord_drake.report.page import _episode_block

    (path,) = sorted(dataset.glob("demo_task/default/data/episode0.hdf5"))
    episode = read_episode(path, images=False)
    clean = _episode_block(episode)
    subgoal = "recover from the push on 'cube'"
    episode.recovery = [[3, 8, subgoal, "", "", 0.0]]
    disturbed = _episode_block(episode)
    assert subgoal not in clean and html_escape(subgoal) in disturbed
    assert "recovery 0" in disturbed

    states = np.array(["left"] * episode.length)

    def image(recovery):
        png = figures.timeline_png("t", episode.stages, states, recovery=recovery)
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)

    red = np.array([0xD7, 0x19, 0x1C])
    plain, marked = image([]), image(episode.recovery)
    assert marked.shape[0] > plain.shape[0]  # a bar more
    assert not np.any(np.all(np.abs(plain - red) < 30, axis=-1))
    assert np.sum(np.all(np.abs(marked - red) < 30, axis=-1)) > 100  # the hatched bar


def html_escape(text: str) -> str:
    import html

    return html.escape(text)
