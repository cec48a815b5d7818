"""One self-contained HTML page describing a generated dataset (images embedded as data URIs).

Sections: per task the episodes kept / seeds tried and the failure reasons (from each
``manifest.json``); the coordination metrics beside the paper's Table 1; STI curves; the
episode-length histogram; for a few episodes per task a stage timeline (one bar per stage,
coloured by which arm works) and the first and last frame of every camera; one embedded video.
"""

from __future__ import annotations

import base64
import html
import time
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bicoord_drake.data.episode import (
    Episode,
    Manifest,
    atomic_path,
    encode_jpeg,
    read_episode,
    read_manifest,
)
from bicoord_drake.data.readers import find_episode_files
from bicoord_drake.metrics.report import (
    COLUMNS,
    PAPER_TABLE1,
    PERCENT_COLUMNS,
    DatasetMetrics,
    measure_paths,
)
from bicoord_drake.report import figures


@dataclass
class TaskSummary:
    """Episodes of one task found under the dataset, with what its manifests say."""

    task: str
    files: list[Path] = field(default_factory=list)
    tried: int | None = None
    kept: int | None = None
    failures: Counter = field(default_factory=Counter)


def _short(reason: str | None, limit: int = 160) -> str:
    text = " ".join((reason or "unknown").split())
    return text if len(text) <= limit else text[: limit - 1] + "…"


def summarize_tasks(paths: Iterable[str | Path]) -> tuple[dict[str, TaskSummary], list[str]]:
    """Per task: its episode files and, from every ``manifest.json`` found, seeds tried, episodes
    kept and failure reasons. Returns the summaries and one error line per unreadable item."""
    paths = [Path(p) for p in paths]
    files, errors = find_episode_files(paths)
    tasks: dict[str, TaskSummary] = {}
    manifests: list[Manifest] = []
    for path in paths:
        for manifest_path in sorted(path.rglob("manifest.json")) if path.is_dir() else []:
            try:
                manifests.append(read_manifest(manifest_path))
            except ValueError as exc:
                errors.append(str(exc))
    for m in manifests:
        t = tasks.setdefault(m.task, TaskSummary(m.task))
        t.tried = (t.tried or 0) + len(m.episodes)
        t.kept = (t.kept or 0) + sum(1 for e in m.episodes if e.success and e.index is not None)
        t.failures.update(_short(e.reason) for e in m.failures)
    for file in files:
        try:
            task = read_episode(file, images=False).task
        except ValueError as exc:
            errors.append(str(exc))
            continue
        tasks.setdefault(task, TaskSummary(task)).files.append(file)
    return dict(sorted(tasks.items())), errors


# --------------------------------------------------------------------------- HTML pieces
def data_uri(data: bytes, mime: str) -> str:
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def _img(data: bytes, mime: str, alt: str, css: str = "") -> str:
    cls = f' class="{css}"' if css else ""
    return f'<img{cls} alt="{html.escape(alt)}" src="{data_uri(data, mime)}">'


def _table(header: Sequence[str], rows: Iterable[Sequence], css: str = "") -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = []
    for row in rows:
        cls = ""
        if isinstance(row, tuple) and len(row) == 2 and isinstance(row[1], str) and row[1] == "ref":
            row, cls = row[0], ' class="ref"'
        body.append(f"<tr{cls}>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>")
    cls = f' class="{css}"' if css else ""
    return f"<table{cls}><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def _fmt(key: str, value: float | None) -> str:
    if value is None:
        return "–"
    return f"{value:.1f}" if key in ("SMT", "TL") else f"{value:.2f}"


def _tasks_section(tasks: dict[str, TaskSummary]) -> str:
    rows = []
    for t in tasks.values():
        kept = "?" if t.kept is None else str(t.kept)
        tried = "?" if t.tried is None else str(t.tried)
        reasons = "<br>".join(f"{n}× {html.escape(r)}" for r, n in t.failures.most_common()) or (
            "none" if t.tried is not None else "no manifest"
        )
        rows.append([html.escape(t.task), f"{kept} / {tried}", str(len(t.files)), reasons])
    table = _table(["task", "kept / tried", "episode files", "failure reasons"], rows)
    return f"<h2>Tasks</h2>{table}"


def _metrics_section(metrics: DatasetMetrics | None) -> str:
    header = ["", "N", *(f"{c} %" if c in PERCENT_COLUMNS else c for c in COLUMNS)]
    rows: list = []
    if metrics is not None:
        for name, row in [*metrics.per_task.items(), ("overall", metrics.overall)]:
            values = row.as_dict()
            rows.append(
                [f"<b>{html.escape(name)}</b>", str(row.n), *(_fmt(k, values[k]) for k in COLUMNS)]
            )
    for name, values in PAPER_TABLE1.items():
        rows.append(([f"paper: {name}", "", *(_fmt(k, values[k]) for k in COLUMNS)], "ref"))
    note = (
        "<p class=note>Coordination metrics of this dataset (means over episodes) above the "
        "paper's Table 1 (grey). SMT: frames both arms act; SMP: their share; MRD/ARD: "
        "minimum/average arm distance relative to the start; STI: area under the STI curve; "
        "TL: length; SN: stages; ON: objects.</p>"
    )
    return f"<h2>Coordination metrics</h2>{_table(header, rows, 'num')}{note}"


_STAGE_HEADER = ["#", "frames", "subgoal", "left arm", "right arm", "arm working (share of frames)"]


def _episode_block(episode: Episode, max_side: int = 240) -> str:
    """Timeline and first/last frames of one episode."""
    from bicoord_drake.data.readers import read_trajectory

    traj = read_trajectory(episode.path)
    states = figures.arm_states(
        traj.left_xyz, traj.right_xyz, traj.left_gripper, traj.right_gripper
    )
    title = f"{episode.task} seed {episode.seed} — {episode.length} frames"
    timeline = figures.timeline_png(title, episode.stages, states)
    stage_rows = []
    for k, (s, e, g, lt, rt, _) in enumerate(episode.stages):
        share = {a: float(np.mean(states[s:e] == a)) for a in ("both", "left", "right")}
        work = ", ".join(f"{a} {100 * v:.0f}%" for a, v in share.items() if v > 0) or "none"
        stage_rows.append(
            [str(k), f"{s}–{e}", html.escape(g), html.escape(lt), html.escape(rt), work]
        )
    frames = []
    for cam in sorted(episode.rgb):
        for label, t in (("first", 0), ("last", episode.length - 1)):
            jpeg = encode_jpeg(episode.image(cam, t), quality=85)
            alt = f"{episode.task} seed {episode.seed} {cam} {label} frame"
            frames.append(
                f"<figure>{_img(jpeg, 'image/jpeg', alt, 'frame')}"
                f"<figcaption>{html.escape(cam)}, {label} (t={t})</figcaption></figure>"
            )
    frames_html = f"<div class=frames>{''.join(frames)}</div>" if frames else "<p>no images</p>"
    return (
        f"<h3>{html.escape(title)}</h3>"
        f"<p class=instr>“{html.escape(episode.instruction)}”</p>"
        f"{_img(timeline, 'image/png', 'stage timeline: ' + title, 'plot')}"
        f"{_table(_STAGE_HEADER, stage_rows)}"
        f"{frames_html}"
    )


def _video_section(tasks: dict[str, TaskSummary]) -> str:
    for t in tasks.values():
        for file in t.files:
            video = file.parent.parent / "video" / f"{file.stem}.mp4"
            if video.is_file():
                episode = read_episode(file)
                poster = ""
                if "head_camera" in episode.rgb:
                    jpeg = encode_jpeg(episode.image("head_camera", 0), quality=85)
                    poster = f' poster="{data_uri(jpeg, "image/jpeg")}"'
                src = data_uri(video.read_bytes(), "video/mp4")
                return (
                    f"<h2>Video</h2><p>{html.escape(t.task)} seed {episode.seed}, head camera "
                    f"({html.escape(video.name)})</p>"
                    f'<video controls muted{poster} src="{src}"></video>'
                )
    return "<h2>Video</h2><p>no episode video found</p>"


_CSS = """
body{font-family:system-ui,sans-serif;margin:24px auto;max-width:1100px;color:#222}
h1{margin-bottom:4px} h2{border-bottom:1px solid #ccc;padding-bottom:4px;margin-top:32px}
table{border-collapse:collapse;margin:8px 0;font-size:14px}
th,td{border:1px solid #ddd;padding:3px 8px;text-align:left;vertical-align:top}
table.num td{text-align:right} table.num td:first-child{text-align:left}
tr.ref td{color:#666;background:#f4f4f4}
.note,.meta{color:#555;font-size:13px} .instr{font-style:italic;color:#444}
.plot{max-width:100%;display:block;margin:8px 0}
.frames{display:flex;flex-wrap:wrap;gap:8px} figure{margin:0}
figcaption{font-size:12px;color:#555} img.frame{width:170px;display:block}
video{max-width:480px;display:block}
"""


def build_report(paths: Sequence[str | Path], episodes_shown: int = 3) -> str:
    """The HTML page for the episodes under ``paths``; ``ValueError`` if there is none."""
    tasks, errors = summarize_tasks(paths)
    if not any(t.files for t in tasks.values()):
        raise ValueError(f"no episode files under {', '.join(map(str, paths))}")
    metrics, trajectories, metric_errors = measure_paths(paths)
    errors += [e for e in metric_errors if e not in errors]
    parts = [
        "<!DOCTYPE html><html lang=en><head><meta charset=utf-8>",
        "<title>bicoord-drake dataset report</title>",
        f"<style>{_CSS}</style></head><body>",
        "<h1>Dataset report</h1>",
        f"<p class=meta>{html.escape(', '.join(map(str, paths)))} · "
        f"{sum(len(t.files) for t in tasks.values())} episodes · "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}</p>",
        _tasks_section(tasks),
        _metrics_section(metrics),
    ]
    if trajectories:
        parts.append("<h2>STI curves</h2>")
        parts.append(_img(figures.sti_png(trajectories), "image/png", "STI curves", "plot"))
        lengths: dict[str, list[int]] = {}
        for t in trajectories:
            lengths.setdefault(t.task, []).append(t.length)
        parts.append("<h2>Episode lengths</h2>")
        hist = figures.length_histogram_png(dict(sorted(lengths.items())))
        parts.append(_img(hist, "image/png", "episode length histogram", "plot"))
    parts.append("<h2>Episodes</h2>")
    for t in tasks.values():
        for file in t.files[:episodes_shown]:
            parts.append(_episode_block(read_episode(file)))
    parts.append(_video_section(tasks))
    if errors:
        items = "".join(f"<li>{html.escape(e)}</li>" for e in errors)
        parts.append(f"<h2>Problems</h2><ul>{items}</ul>")
    parts.append("</body></html>")
    return "\n".join(parts)


def write_report(paths: Sequence[str | Path], out: str | Path, episodes_shown: int = 3) -> Path:
    """Write :func:`build_report` to ``out`` atomically."""
    page = build_report(paths, episodes_shown)
    out = Path(out)
    with atomic_path(out) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return out
