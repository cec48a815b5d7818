"""One self-contained HTML page describing a generated dataset (images embedded as data URIs).

Sections: per task the episodes kept / seeds tried and the failure reasons (from each
``manifest.json``); the coordination metrics beside the paper's Table 1 (SMT, SMP, STI under both
movement tests, the paper's and the jitter-free one, each column naming its test; the start
distance d0 and MRD, ARD in metres beside the ratios); STI curves, one panel per test; the
episode-length histogram; for a few episodes per task a stage timeline (one bar per stage,
coloured by which arm works under the jitter-free test, with each stage's shares under both
tests; a disturbed episode's recovery segments as hatched bars of their own) and the first
and last frame of every camera; one embedded video.
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
from bicoord_drake.metrics.coordination import JITTER_FREE_TEST, MOVEMENT_TESTS, PAPER_TEST
from bicoord_drake.metrics.report import (
    ARD_M_COLUMN,
    D0_COLUMN,
    MRD_M_COLUMN,
    PAPER_TABLE1,
    REFERENCE_D0,
    TEST_COLUMNS,
    DatasetMetrics,
    column_name,
    format_cell,
    header,
    measure_paths,
    movement_tests_note,
    table_columns,
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


def _fmt(column: str, value: float | None) -> str:
    return format_cell(column, value, missing="–")


def paper_row(name: str, columns: Sequence[str]) -> dict[str, float | None]:
    """The paper's Table 1 row ``name`` in our columns: its SMT, SMP, STI under the paper's test
    (its only test), d0 and the metre values where the reference robot's d0 is established
    (:data:`~bicoord_drake.metrics.report.REFERENCE_D0`), ``None`` elsewhere."""
    values = PAPER_TABLE1[name]
    row: dict[str, float | None] = dict.fromkeys(columns)
    for metric in TEST_COLUMNS:
        row[column_name(metric, PAPER_TEST.name)] = values[metric]
    for metric in ("MRD", "ARD", "TL", "SN", "ON"):
        row[metric] = values[metric]
    d0 = REFERENCE_D0.get(name)
    if d0 is not None:
        row[D0_COLUMN] = d0
        row[MRD_M_COLUMN] = d0 * values["MRD"] / 100.0
        row[ARD_M_COLUMN] = d0 * values["ARD"] / 100.0
    return {c: row[c] for c in columns}


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
    tests = metrics.tests if metrics is not None else MOVEMENT_TESTS
    columns = [c for c in table_columns(tests) if c != "PL"]
    head = ["", "N", *(header(c) for c in columns)]
    rows: list = []
    if metrics is not None:
        for name, row in metrics.rows():
            values = row.columns(tests)
            cells = (_fmt(c, values[c]) for c in columns)
            rows.append([f"<b>{html.escape(name)}</b>", str(row.n), *cells])
    for name in PAPER_TABLE1:
        values = paper_row(name, columns)
        rows.append(([f"paper: {name}", "", *(_fmt(c, values[c]) for c in columns)], "ref"))
    d0_refs = ", ".join(f"{name} {d0:.3f} m" for name, d0 in REFERENCE_D0.items())
    note = (
        "<p class=note>Coordination metrics of this dataset (means over episodes) above the "
        "paper's Table 1 (grey). SMT: frames both arms act; SMP: their share; STI: area under "
        "the STI curve; each of the three is shown under both movement tests, named in its "
        f"header. {html.escape(movement_tests_note(tests))} The paper's rows use its own test: "
        f"compare them with the ({PAPER_TEST.name}) columns. d0: distance between the two TCPs "
        "in the first frame; MRD/ARD: minimum/average arm distance relative to d0, beside the "
        "same in metres. Ratios compare across datasets only at the same d0. The reference "
        f"robot's d0 is established for {html.escape(d0_refs)} (docs/metrics.md); that row's "
        "metres are its d0 times its ratios. TL: length; SN: stages; ON: objects.</p>"
    )
    return f"<h2>Coordination metrics</h2>{_table(head, rows, 'num')}{note}"


_STAGE_HEADER = [
    "#",
    "frames",
    "subgoal",
    "left arm",
    "right arm",
    f"arm working, {JITTER_FREE_TEST.name} test (share of frames)",
    f"arm working, {PAPER_TEST.name} (share of frames)",
]


def _shares(states: np.ndarray) -> str:
    share = {a: float(np.mean(states == a)) for a in ("both", "left", "right")}
    return ", ".join(f"{a} {100 * v:.0f}%" for a, v in share.items() if v > 0) or "none"


def _episode_block(episode: Episode, max_side: int = 240) -> str:
    """Timeline and first/last frames of one episode."""
    from bicoord_drake.data.readers import read_trajectory

    traj = read_trajectory(episode.path)
    signals = (traj.left_xyz, traj.right_xyz, traj.left_gripper, traj.right_gripper)
    states = figures.arm_states(*signals, move_tol=JITTER_FREE_TEST.move_tol)
    paper_states = figures.arm_states(*signals, move_tol=PAPER_TEST.move_tol)
    title = f"{episode.task} seed {episode.seed} — {episode.length} frames"
    recovery = list(getattr(episode, "recovery", None) or [])
    timeline = figures.timeline_png(
        title, episode.stages, states, test=JITTER_FREE_TEST.name, recovery=recovery
    )
    stage_rows = []
    numbered = [(str(k), row) for k, row in enumerate(episode.stages)]
    numbered += [(f"recovery {k}", row) for k, row in enumerate(recovery)]
    for k, (s, e, g, lt, rt, _) in numbered:
        stage_rows.append(
            [
                *(k, f"{s}–{e}", html.escape(g), html.escape(lt), html.escape(rt)),
                _shares(states[s:e]),
                _shares(paper_states[s:e]),
            ]
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
