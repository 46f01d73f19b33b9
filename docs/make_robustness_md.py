"""Write docs/robustness_results.md from finished sweeps (``python evaluate.py --sweep ...``).

Usage::

    python docs/make_robustness_md.py SWEEP_DIR [SWEEP_DIR ...] --out PAGE.md
        [--figures DIR] [--title TEXT] [--intro FILE] [--names NAME ...]
        [--figure-prefix sweep] [--reference CONTROLLER] [--level-costs]
        [--fault-split PUBLICATION]

Each sweep directory (holding the sweep.json manifest) becomes one part: its command, the levels
not finished yet (if any), and per axis the summary (area under the success curve, worst-10%
tail) and the table of every level, with the profile's figure copied under ``--figures`` (default:
``_static`` beside the page, as docs/_static for a page of docs/). Every
level's results are read back checked (``evaluation.experiments.sweep.load_sweep``).

The ``--intro`` file is a template (``docs/make_prose_md.py``): its placeholders
(``{{ rate lab_day_sweep@actuation_delay=4 koopman-nmpc }}``) are filled from the sweeps given,
each named by its file.

With ``--names`` (one per sweep) the parts are titled by them, and when the page has two or more
parts, it opens with one overview of every controller over every part's axes: the same
axis swept under different settings (e.g. ``movers.count`` for each mover behaviour of
``--crowd``) side by side.

With ``--fault-split`` (a sweep among movers whose records carry the fault rule's fields, e.g.
``data/crowd_faults``), the page ends with its collisions split by fault and its success with and
without the collisions no robot could avoid (:mod:`evaluation.reports.sections.fault_split`); while that
publication is absent, the section says it is pending and names the command that makes it, and a
publication whose records predate the fields is refused by name.
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from evaluation.exit_codes import BAD_INPUT_EXIT, SUCCESS_EXIT  # noqa: E402
from evaluation.experiments.sweep import load_sweep  # noqa: E402
from evaluation.reports.figures import save_profile_figures  # noqa: E402
from evaluation.reports.sections import level_cost_section, markdown, overview_section, robustness_sections  # noqa: E402
from evaluation.reports.sections.fault_split import fault_rows, fault_section, pending_section  # noqa: E402
from evaluation.stats.robustness import AxisProfile, level_costs, profiles  # noqa: E402
from koopman_envs.files import write_atomic  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the page scripts beside this one
from make_prose_md import expand_template  # noqa: E402

INTRO = """Robustness profiles (not in the paper): every built-in controller at every level of one
runtime-uncertainty setting at a time, the others perfect, on the paper's maps with 3 robots.
Trial i uses seed i at every level, so the maps, starts and slip draws are the same at every
level and the curves are paired ([Robustness profiles](robustness.md),
[Runtime uncertainty](uncertainty.md)). A level that resolves to the same settings as another
(every axis at 0) is run once and serves every axis. Regenerate with the commands below, then
`python docs/make_robustness_md.py SWEEP_DIR ... --out PAGE.md`."""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("sweeps", nargs="+", help="sweep output directories")
    # no default page: the published ones are tracked files (docs/make_pages.py names them)
    parser.add_argument("--out", required=True, help="the page to write, e.g. docs/robustness_results.md")
    parser.add_argument("--figures", help="where figures go (default: _static beside --out)")
    parser.add_argument("--title", default="Robustness results")
    parser.add_argument(
        "--intro", type=Path, help="a Markdown file whose text opens the page (default: the sweeps' intro)"
    )
    parser.add_argument("--names", nargs="+", help="one title per sweep (default: Sweep 1, Sweep 2, ...)")
    parser.add_argument(
        "--figure-prefix",
        default="sweep",
        help="figure file names start with PREFIX<number>_ (default: sweep)",
    )
    parser.add_argument(
        "--reference", help="the controller every other is paired against (default: each sweep's own)"
    )
    parser.add_argument(
        "--level-costs",
        action="store_true",
        help="add per part what each level costs each controller against the axis's first level "
        "(paired, Holm-adjusted; the sensing protocol's 'what seeing through a lidar costs')",
    )
    parser.add_argument(
        "--fault-split",
        metavar="PUBLICATION",
        help="end the page with the collisions of this sweep among movers split by fault "
        "(e.g. data/crowd_faults; while it is absent, a section saying it is pending)",
    )
    return parser


def _sweep(directory: str, reference: str | None) -> tuple[dict, list[str], dict, list[AxisProfile]]:
    """A sweep's finished axes (those with two levels or more), its unfinished levels, its
    manifest and its profiles; ``ValueError`` with the page's message when it has none."""
    done, missing, manifest = load_sweep(directory)
    # an axis with one finished level (its 0, which every axis shares) has no profile yet
    shown = {key: levels for key, levels in done.items() if len(levels) >= 2}
    if not shown:
        raise ValueError(f"no axis of the sweep in {directory!r} has two finished levels")
    try:
        axes = profiles(shown, reference or manifest.get("reference"))
    except ValueError as exc:
        raise ValueError(f"{exc} (sweep {directory!r})") from exc
    return shown, missing, manifest, axes


def _part(
    index: int, name: str, sweep: tuple[dict, list[str], dict, list[AxisProfile]], args: argparse.Namespace
) -> tuple[list[str], list[AxisProfile]]:
    """One sweep's part of the page (its figures saved) and its axes named by the part."""
    done, missing, manifest, axes = sweep
    figures = Path(args.figures) if args.figures else Path(args.out).parent / "_static"
    parts = [f"## {name}\n\nCommand: `{manifest.get('command', '')}`"]
    if missing:
        parts.append(f"Levels not finished yet, left out: {', '.join(missing)}.")
    paths = save_profile_figures(axes, figures)
    for profile, path in zip(axes, paths):
        target = path.with_name(f"{args.figure_prefix}{index + 1}_{path.name}")
        path.replace(target)
        link = os.path.relpath(target, Path(args.out).resolve().parent)
        parts.append(f"![{name}: robustness to {profile.key}]({link})")
    parts.append(markdown(robustness_sections(axes)).replace("## Robustness", "### Robustness"))
    costs = level_cost_section(level_costs(done)) if args.level_costs else None
    if costs is not None:
        parts.append(markdown([costs]).replace("## What", "### What"))
    return parts, [replace(profile, key=f"{name}: {profile.key}") for profile in axes]


def _fault_split(publication: str) -> str:
    """The page's section of collisions by fault from ``publication`` (a sweep of one axis among
    movers: a publication or a run's directory), or the pending section while it is absent;
    ``ValueError`` naming a publication that cannot be split."""
    if not Path(publication).exists():
        return markdown([pending_section(publication, Path(publication).name.removesuffix(".tar.xz"))])
    done, missing, manifest = load_sweep(publication, from_logs=True)
    if len(done) != 1:
        raise ValueError(f"--fault-split {publication!r} sweeps {len(done)} axes; give a sweep of one axis")
    ((key, levels),) = done.items()
    return markdown(
        [fault_section(fault_rows(levels, publication), key, manifest.get("command", ""), missing)]
    )


def _refused(args: argparse.Namespace) -> str | None:
    """What is wrong with the arguments, or None."""
    if args.names is not None and len(args.names) != len(args.sweeps):
        return f"--names gives {len(args.names)} name(s) for {len(args.sweeps)} sweep(s); give one per sweep"
    if args.intro is not None and not args.intro.is_file():
        return f"--intro {str(args.intro)!r} is not a file"
    return None


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    refused = _refused(args)
    if refused is not None:
        print(f"error: {refused}", file=sys.stderr)
        return BAD_INPUT_EXIT
    out = Path(args.out)
    figures = Path(args.figures) if args.figures else out.parent / "_static"
    names = args.names or [f"Sweep {index + 1}" for index in range(len(args.sweeps))]
    named_axes: list[AxisProfile] = []
    try:  # the intro's numbers are placeholders filled from these sweeps (docs/make_prose_md.py)
        intro = INTRO if args.intro is None else expand_template(args.intro, args.sweeps).strip()
    except ValueError as exc:  # the message names the template and the placeholder
        print(f"error: {exc}", file=sys.stderr)
        return BAD_INPUT_EXIT
    parts = [f"# {args.title}", intro]
    for index, (directory, name) in enumerate(zip(args.sweeps, names)):
        try:
            sweep = _sweep(directory, args.reference)
        except ValueError as exc:  # the message names the sweep
            print(f"error: {exc}", file=sys.stderr)
            return BAD_INPUT_EXIT
        part, axes = _part(index, name, sweep, args)
        parts += part
        named_axes += axes
    if args.names is not None and len(args.sweeps) > 1:
        scope = (
            "Every part's axes side by side, named by part: each part is one sweep, its setting "
            "varied alone under that part's other settings."
        )
        overview = overview_section(named_axes, scope, "Overview of every part")
        if overview is not None:
            parts.insert(2, markdown([overview]))
    if args.fault_split is not None:
        try:
            parts.append(_fault_split(args.fault_split))
        except ValueError as exc:  # the message names the publication (and the episode and field)
            print(f"error: {exc}", file=sys.stderr)
            return BAD_INPUT_EXIT
    write_atomic(out, "\n\n".join(parts) + "\n")
    print(f"wrote {out} and {len(args.sweeps)} sweep(s) of figures in {figures}")
    return SUCCESS_EXIT


if __name__ == "__main__":
    raise SystemExit(main())
