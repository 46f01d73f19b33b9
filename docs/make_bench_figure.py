"""Draw example layouts of the benchmark suites, one row per family, for docs/benchmark.md.

``python docs/make_bench_figure.py --out docs/_static/bench_layouts.png``

The first layouts of each family in ``koopnav-bench-v1``'s validation split (target reaching on
the left, formation on the right), as stored: obstacles in grey, starts as hollow discs, targets
as crosses, each robot's shortest path (the grid planner of the measures) dashed, the arena
dotted. The title gives the layout, its tier and its measures.
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import Circle, Rectangle

from koopman_envs.files import write_atomic
from koopman_envs.suites import FAMILIES, load_suite
from koopman_envs.suites.measures import ARENA
from koopman_envs.suites.planner import shortest_path

COLOURS = ("tab:blue", "tab:orange", "tab:green")
PER_TASK = 2  # layouts per family and task


def _draw(ax: plt.Axes, layout: object) -> None:
    spec = layout.spec  # type: ignore[attr-defined]
    ax.add_patch(
        Rectangle((ARENA[0], ARENA[2]), ARENA[1] - ARENA[0], ARENA[3] - ARENA[2], fill=False, ls=":", lw=0.6)
    )
    for x, y, r in spec.obstacles:
        ax.add_patch(Circle((x, y), r, color="0.55"))
    for i, (start, target) in enumerate(zip(spec.starts, spec.targets)):
        colour = COLOURS[i % len(COLOURS)]
        path = shortest_path(spec.obstacles, start, target)
        if path is not None:
            ax.plot(path[:, 0], path[:, 1], "--", color=colour, lw=0.9)
        ax.add_patch(Circle(start[:2], 0.2, fill=False, color=colour, lw=1.2))
        ax.plot(*target[:2], "x", color=colour, ms=6, mew=1.6)
    m = layout.measures  # type: ignore[attr-defined]
    ax.set_title(
        f"{layout.id} {layout.tier}\ngap {m['gap']:.2f} m, tort. {m['tortuosity']:.2f}, dens. {m['density']:.3f}",  # type: ignore[attr-defined]
        fontsize=7,
    )
    ax.set_xlim(ARENA[0] - 0.5, ARENA[1] + 0.5)
    ax.set_ylim(ARENA[2] - 0.5, ARENA[3] + 0.5)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    # no default: the figure is a tracked file, written only when named
    parser.add_argument("--out", required=True, help="the PNG to write (docs/_static/bench_layouts.png)")
    args = parser.parse_args(argv)
    suites = [load_suite("koopnav-bench-v1", task, "validation") for task in ("target_reaching", "formation")]
    fig, axes = plt.subplots(len(FAMILIES), 2 * PER_TASK, figsize=(2.6 * 2 * PER_TASK, 2.9 * len(FAMILIES)))
    for row, family in enumerate(FAMILIES):
        for t, suite in enumerate(suites):
            chosen = [layout for layout in suite.layouts if layout.family == family][:PER_TASK]
            for k, layout in enumerate(chosen):
                _draw(axes[row, t * PER_TASK + k], layout)
        axes[row, 0].set_ylabel(family, fontsize=10)
    fig.suptitle(
        "koopnav-bench-v1 (validation): target reaching (left two), formation (right two)", fontsize=10
    )
    fig.tight_layout()
    write_atomic(args.out, lambda temporary: fig.savefig(temporary, dpi=110))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
