"""The reports as self-contained HTML pages: a run's (``OUT/index.html``) and a sweep's
(``OUT/robustness.html``), each written by :func:`write_page`.

A run's page holds the run configuration, the leaderboard, the paired comparisons and the
per-controller tables: the sections of :func:`evaluation.reports.sections.sections`, which the Markdown
report renders too (the same formatted cells), every figure as an embedded PNG and, for each cell whose
episode record names an ``animation`` (a path relative to the output directory), that animation.
A sweep's page holds its figures and the sections of :func:`evaluation.reports.sections.robustness_sections`.

Nothing is loaded from anywhere: CSS and JavaScript are inline, images are ``data:`` URIs, and
a Content-Security-Policy forbids every other source, so the page opens offline and from an
e-mail attachment alike. Every table sorts by a click on a column header (numbers such as
``80% [49-94]``, ``8/10 [49-94%]`` or ``12.3 [10.1-14.0]`` by their value, ``-`` last).
Every string that comes from data (controller labels are user text) is HTML-escaped.
"""

from __future__ import annotations

import base64
import mimetypes
import os
from collections.abc import Iterable, Sequence
from html import escape
from pathlib import Path
from typing import Any

import koopman_envs
from evaluation.reports.sections import (
    Items,
    Note,
    Section,
    Table,
    TableBlock,
    sections,
    suite_heading,
    task_label,
)
from evaluation.stats.run_data import RunData
from koopman_envs.files import write_atomic

__all__ = ["render_html", "render_page", "write_html", "write_page"]

#: No source but the page itself and ``data:`` images.
_CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'"

_CSS = """
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", sans-serif; color: #222;
       max-width: 80rem; margin: 1.5rem auto; padding: 0 1rem; }
h1 { font-size: 1.5rem; } h2 { font-size: 1.2rem; margin-top: 2rem; border-bottom: 1px solid #ddd; }
h3 { font-size: 1rem; margin-bottom: .3rem; }
.note { color: #555; max-width: 60rem; }
.scroll { overflow-x: auto; }
table { border-collapse: collapse; margin: .4rem 0 1rem; font-variant-numeric: tabular-nums; }
th, td { border: 1px solid #ccc; padding: .25rem .5rem; text-align: left; white-space: nowrap; }
th { background: #f2f2f2; white-space: normal; vertical-align: bottom; }
th button { all: unset; cursor: pointer; }
th button:focus-visible { outline: 2px solid #36c; }
th[aria-sort="ascending"] button::after { content: " \\25B2"; }
th[aria-sort="descending"] button::after { content: " \\25BC"; }
tbody tr:nth-child(even) { background: #fafafa; }
dl.config { display: grid; grid-template-columns: max-content 1fr; gap: .15rem 1rem; }
dl.config dt { font-weight: 600; } dl.config dd { margin: 0; }
.gallery { display: flex; flex-wrap: wrap; gap: 1rem; }
figure { margin: 0; } figure img { max-width: 100%; height: auto; border: 1px solid #eee; }
figcaption { font-size: 12px; color: #555; max-width: 30rem; overflow-wrap: anywhere; }
"""

# Sorts every <table class="sortable"> by the clicked header: numeric when every non-empty
# cell of the column reads as a number, else text; "-" and empty cells last in both directions.
_JS = r"""
(function () {
  "use strict";
  var NUMBER = /^([<>]?)\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?)(?:\s*(%)|\/(\d+(?:\.\d+)?))?/i;
  // "80% [49-94]" -> 0.8, "8/10 [49-94%]" -> 0.8, "12.3 [10.1-14.0]" -> 12.3, "+5 [-3, +12]" -> 5,
  // "12.3+-1.2" -> 12.3, "<0.001" -> just under 0.001, "1,000" -> 1000, "-" or "" -> null, text -> NaN
  function sortKey(text) {
    var t = String(text).trim().replace(/(\d),(?=\d{3}(?!\d))/g, "$1");
    if (t === "" || t === "-" || t === "\u2013" || t === "\u2014") { return null; }
    var m = NUMBER.exec(t);
    if (!m) { return NaN; }
    var v = parseFloat(m[2]);
    if (m[3] === "%") { v = v / 100; }
    else if (m[4] !== undefined) { v = parseFloat(m[4]) > 0 ? v / parseFloat(m[4]) : v; }
    if (m[1] === "<") { v -= 1e-12 * Math.max(1, Math.abs(v)); }
    if (m[1] === ">") { v += 1e-12 * Math.max(1, Math.abs(v)); }
    return v;
  }
  window.koopnavSortKey = sortKey;

  function cellText(row, col) {
    var cell = row.cells[col];
    return cell ? cell.textContent : "";
  }

  function sortTable(table, col, descending) {
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    var keys = rows.map(function (r) { return sortKey(cellText(r, col)); });
    var numeric = keys.every(function (k) { return k === null || !isNaN(k); });
    var order = rows.map(function (r, i) { return i; });
    order.sort(function (i, j) {
      var a = keys[i], b = keys[j];
      if (a === null || b === null) {
        if (a === null && b === null) { return i - j; }
        return a === null ? 1 : -1;  // empty cells last either way
      }
      var c = numeric ? a - b : cellText(rows[i], col).trim().localeCompare(
        cellText(rows[j], col).trim(), undefined, {numeric: true, sensitivity: "base"});
      if (descending) { c = -c; }
      return c !== 0 ? c : Number(rows[i].dataset.index) - Number(rows[j].dataset.index);
    });
    order.forEach(function (i) { body.appendChild(rows[i]); });
  }

  function init(table) {
    Array.prototype.forEach.call(table.tBodies[0].rows, function (r, i) { r.dataset.index = String(i); });
    var headers = table.tHead.rows[0].cells;
    Array.prototype.forEach.call(headers, function (th, col) {
      th.addEventListener("click", function () {
        var descending = th.getAttribute("aria-sort") === "ascending";
        Array.prototype.forEach.call(headers, function (h) { h.removeAttribute("aria-sort"); });
        sortTable(table, col, descending);
        th.setAttribute("aria-sort", descending ? "descending" : "ascending");
      });
    });
  }

  document.querySelectorAll("table.sortable").forEach(init);
})();
"""


def _e(value: Any) -> str:
    """HTML-escaped text of ``value`` (quotes too, so it is safe in attributes)."""
    return escape(str(value), quote=True)


def _text(value: Any) -> str:
    """Plain text of a configuration value: lists joined by commas, mappings as ``key: value``."""
    if value is None:
        return "-"
    if isinstance(value, dict):
        return "; ".join(f"{k}: {_text(v)}" for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return ", ".join(_text(v) for v in value)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _section(section: Section) -> str:
    """One report section (:func:`evaluation.reports.sections.sections`) as HTML."""
    out = [f'<h2 id="{_e(section.anchor)}">{_e(section.title)}</h2>']
    for block in section.blocks:
        if isinstance(block, Note):
            out.append(f'<p class="note">{_e(block.text)}</p>')
        elif isinstance(block, TableBlock):
            if block.caption:
                out.append(f"<h3>{_e(block.caption)}</h3>")
            out.append(_table(block.table))
        elif isinstance(block, Items):
            out += [
                "<ul>",
                *(f"<li><code>{_e(code)}</code>: {_e(text)}</li>" for code, text in block.entries),
                "</ul>",
            ]
    return "\n".join(out)


def _table(table: Table, caption: str = "") -> str:
    """A :data:`~evaluation.reports.sections.Table` as a sortable HTML table."""
    header, rows = table
    head = "".join(f'<th scope="col"><button type="button">{_e(h)}</button></th>' for h in header)
    body = "\n".join("<tr>" + "".join(f"<td>{_e(c)}</td>" for c in row) + "</tr>" for row in rows)
    cap = f"<caption>{_e(caption)}</caption>" if caption else ""
    return (
        f'<div class="scroll"><table class="sortable">{cap}<thead><tr>{head}</tr></thead>\n'
        f"<tbody>\n{body}\n</tbody></table></div>"
    )


def _data_uri(path: Path) -> str | None:
    """``data:`` URI of an image file, or None when it is not an image."""
    mime = mimetypes.guess_type(path.name)[0] or ""
    if not mime.startswith("image/"):
        return None
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def _figure(path: Path, caption: str) -> str:
    uri = _data_uri(path)
    if uri is None:
        return f'<p class="note">{_e(path.name)}: not an image, not embedded.</p>'
    return f'<figure><img src="{uri}" alt="{_e(caption)}"><figcaption>{_e(caption)}</figcaption></figure>'


def _config_section(results: RunData) -> str:
    config = results.config
    items: list[tuple[str, str]] = []
    env_ids = config.get("env_ids") or list(dict.fromkeys(c.env_id for c in results.cells))
    items.append(("Environments", ", ".join(f"{e} ({task_label(e)})" for e in env_ids)))
    labels = config.get("controllers") or list(dict.fromkeys(c.controller for c in results.cells))
    items.append(("Controllers", _text(labels)))
    for cfg in config.get("controller_configs") or []:
        if cfg.get("options") or cfg.get("label") != cfg.get("name"):
            options = _text(cfg.get("options")) if cfg.get("options") else "default options"
            items.append((f"{cfg.get('label')}", f"{cfg.get('name')}, {options}"))
    maps = config.get("maps") or list(dict.fromkeys(c.map for c in results.cells))
    if isinstance(maps, dict) and len({tuple(v) for v in maps.values()}) == 1:
        maps = next(iter(maps.values()))  # the same maps for every task
    items.append(("Maps", _text(maps)))
    items.append(("Slips", _text(config.get("slips") or list(dict.fromkeys(c.slip for c in results.cells)))))
    if config.get("suite"):  # a suite run: its label(s), and its episodes are per layout
        items.append(("Suite", suite_heading(config)))
    items.append(
        ("Episodes per layout" if config.get("suite") else "Episodes per cell", _text(config.get("episodes")))
    )
    items.append(("Seed", _text(config.get("seed"))))
    calibration = config.get("calibration") or {}
    if calibration:
        budget = calibration.get("budget")
        budget_text = f"{budget:,}" if isinstance(budget, int) else _text(budget)
        seed = _text(calibration.get("seed"))
        items.append(("Calibration budget", f"{budget_text} team-transitions (seed {seed})"))
    settings = {
        "start_noise": "Start noise",
        "tolerance": "Tolerance",
        "max_episode_steps": "Max. episode steps",
        "workers": "Workers",
        "backend": "Backend",
    }
    for key, name in settings.items():
        if key in config:
            items.append((name, _text(config[key])))
    if isinstance(config.get("wall_seconds"), (int, float)):
        items.append(("Wall time", f"{config['wall_seconds']:.0f} s"))
    failed = len(results.failed_episodes)
    items.append(("Episodes run", f"{len(results.records)}" + (f" ({failed} raised)" if failed else "")))
    items.append(("koopnav", koopman_envs.__version__))
    out = ['<h2 id="configuration">Run configuration</h2>', '<dl class="config">']
    out += [f"<dt>{_e(k)}</dt><dd>{_e(v)}</dd>" for k, v in items]
    out.append("</dl>")
    if config.get("command"):
        out.append(f"<p>Regenerate with <code>{_e(_text(config['command']))}</code></p>")
    return "\n".join(out)


def _animations(results: RunData, out_dir: Path) -> list[str]:
    """One embedded animation per cell whose records name one (trial 0's first)."""
    out = []
    for cell in results.cells:
        where = (cell.env_id, cell.controller, cell.map, cell.slip)
        recs = [
            r
            for r in results.records
            if r.get("animation") and (r["env_id"], r["controller"], r["map"], r["slip"]) == where
        ]
        if not recs:
            continue
        rec = min(recs, key=lambda r: (r.get("trial") != 0, r.get("trial") or 0))
        caption = (
            f"{cell.controller} | {task_label(cell.env_id)} | {cell.map} | {cell.slip} | "
            f"trial {rec.get('trial', 0)}"
        )
        path = out_dir / str(rec["animation"])
        if path.is_file():
            out.append(_figure(path, caption))
        else:
            out.append(f'<p class="note">{_e(caption)}: animation {_e(rec["animation"])} not found.</p>')
    return out


def _page_head(title: str) -> list[str]:
    """The opening lines of a report page: doctype, policy, style, title and the sorting hint."""
    return [
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        f'<meta http-equiv="Content-Security-Policy" content="{_CSP}">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{_e(title)}</title>",
        f"<style>{_CSS}</style>",
        "</head>",
        "<body>",
        f"<h1>{_e(title)}</h1>",
        '<p class="note">Click a column header to sort a table; click again to reverse.</p>',
    ]


def _page(title: str, body: Iterable[str]) -> str:
    """A self-contained page: its head (policy, style, title, sorting hint), ``body`` (HTML
    parts in order) and the sorting script."""
    return "\n".join([*_page_head(title), *body, f"<script>{_JS}</script>", "</body>", "</html>", ""])


def _gallery(anchor: str, title: str, items: Sequence[str]) -> list[str]:
    """A titled gallery of figures or animations (nothing for no item)."""
    if not items:
        return []
    return [f'<h2 id="{_e(anchor)}">{_e(title)}</h2>', '<div class="gallery">', *items, "</div>"]


def _figures(figures: Iterable[str | os.PathLike]) -> list[str]:
    """The figures section of a page: every figure embedded, captioned by its file name."""
    return _gallery("figures", "Figures", [_figure(Path(f), Path(f).name) for f in figures])


def render_html(
    results: RunData, out_dir: str | os.PathLike, figures: Iterable[str | os.PathLike] | None = None
) -> str:
    """The report page of a run, as one self-contained HTML document.

    Parameters
    ----------
    results : RunData
        The run.
    out_dir : str or path-like
        The run's output directory; ``animation`` paths of episode records are relative to it.
    figures : iterable of str or path-like, optional
        PNG figures to embed (default: every ``*.png`` in ``out_dir/figures``), shown sorted by
        file name.

    Returns
    -------
    str
        The HTML text: no external resource, every data string escaped.
    """
    out = Path(out_dir)
    if figures is None:
        figures = sorted((out / "figures").glob("*.png")) if (out / "figures").is_dir() else []
    figure_paths = sorted((Path(f) for f in figures), key=lambda p: p.name)
    body = [_config_section(results), *(_section(section) for section in sections(results))]
    body += _figures(figure_paths)
    body += _gallery("animations", "Animations", _animations(results, out))
    return _page("KoopNav results", body)


def render_page(title: str, report: Sequence[Section], figures: Iterable[str | os.PathLike] = ()) -> str:
    """A self-contained page of report sections after their figures (a sweep's robustness page).

    Parameters
    ----------
    title : str
        The page's title and heading.
    report : sequence of Section
        The report's sections (:mod:`evaluation.reports.sections`), in order.
    figures : iterable of str or path-like, optional
        PNG figures to embed above the sections, in the given order.

    Returns
    -------
    str
        The HTML text: no external resource, every data string escaped.
    """
    return _page(title, [*_figures(figures), *(_section(section) for section in report)])


def write_page(path: str | os.PathLike, page: str) -> Path:
    """Write a page to ``path``, its folder created if missing: the one writer of every report
    page, a run's and a sweep's.

    Parameters
    ----------
    path : str or path-like
        Where the page goes (``OUT/index.html``, ``OUT/robustness.html``).
    page : str
        The page's HTML (:func:`render_html`, :func:`render_page`).

    Returns
    -------
    pathlib.Path
        The page's path.
    """
    return write_atomic(path, page)


def write_html(
    results: RunData, out_dir: str | os.PathLike, figures: Sequence[str | os.PathLike] | None = None
) -> Path:
    """Write ``out_dir/index.html``, the self-contained report page (see :func:`render_html`).

    Parameters
    ----------
    results : RunData
        The run.
    out_dir : str or path-like
        The run's output directory (created if missing).
    figures : sequence of str or path-like, optional
        PNG figures to embed (default: every ``*.png`` in ``out_dir/figures``).

    Returns
    -------
    pathlib.Path
        The page's path.
    """
    return write_page(Path(out_dir) / "index.html", render_html(results, out_dir, figures))
