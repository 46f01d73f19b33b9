"""Write docs/results.md from a ``python evaluate.py --paper`` run, beside the paper's tables.

Usage: ``python docs/make_results_md.py results_paper/results.json [more results.json ...] [--wall SECONDS]``
(cells of later files are added to those of the first, e.g. a separate ``--controllers rl-ppo`` run).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

# The paper's numbers (SPEC section 5): SR and final distances [cm], robots 1-3.
PAPER = {
    ("koopman-nmpc", "map1"): {"nominal": "10/10 (0.9, 1.9, 1.9)", "low": "9/10 (3.1, 2.7, 6.6)", "high": "8/10 (1.9, 2.7, 6.6)"},
    ("koopman-nmpc", "map2"): {"nominal": "10/10 (2.8, 1.8, 2.3)", "low": "9/10 (5.0, 2.4, 6.4)", "high": "6/10 (4.9, 2.6, 4.8)"},
    ("nominal-nmpc", "map1"): {"nominal": "10/10 (1.8, 1.5, 15.6)", "low": "8/10 (1.3, 1.8, 3.5)", "high": "3/10 (1.1, 2.4, 4.0)"},
    ("nominal-nmpc", "map2"): {"nominal": "0/10", "low": "1/10 (2.4, 0.5, 3.4)", "high": "0/10"},
    ("koopman-nmpc", "map3"): {"nominal": "10/10 (0.9, 1.9, 1.9)", "low": "9/10 (1.7, 4.5, 3.9)", "high": "8/10 (1.7, 2.4, 1.1)"},
    ("koopman-nmpc", "map4"): {"nominal": "10/10 (2.5, 7.0, 7.5)", "low": "8/10 (2.6, 8.4, 9.6)", "high": "8/10 (3.0, 6.6, 13.5)"},
    ("nominal-nmpc", "map3"): {"nominal": "10/10 (0.5, 1.0, 1.1)", "low": "0/10", "high": "0/10"},
    ("nominal-nmpc", "map4"): {"nominal": "10/10 (1.7, 4.1, 3.8)", "low": "4/10 (2.0, 3.7, 8.6)", "high": "0/10"},
    ("consensus", "map3"): {"nominal": "10/10 (4.1, 76.3, 45.1)", "low": "9/10 (4.1, 148.3, 50.3)", "high": "9/10 (4.1, 158.3, 51.0)"},
    ("consensus", "map4"): {"nominal": "10/10 (7.4, 71.4, 82.6)", "low": "10/10 (7.4, 69.5, 113.2)", "high": "7/10 (7.4, 69.8, 90.9)"},
}
TABLES = [
    ("Table 1: Koopman-NMPC, target reaching", "KoopNav-TargetReaching-v0", "koopman-nmpc"),
    ("Table 2: nominal NMPC, target reaching", "KoopNav-TargetReaching-v0", "nominal-nmpc"),
    ("Table 3: Koopman-NMPC, formation", "KoopNav-Formation-v0", "koopman-nmpc"),
    ("Table 4: nominal NMPC, formation", "KoopNav-Formation-v0", "nominal-nmpc"),
    ("Table 5: consensus (collision avoidance on), formation", "KoopNav-Formation-v0", "consensus"),
    ("Not in the paper: consensus, target reaching", "KoopNav-TargetReaching-v0", "consensus"),
    ("Not in the paper: RL baseline (rl-ppo), target reaching", "KoopNav-TargetReaching-v0", "rl-ppo"),
    ("Not in the paper: RL baseline (rl-ppo), formation", "KoopNav-Formation-v0", "rl-ppo"),
]


def fmt(cell: dict) -> tuple[str, str, str]:
    valid = cell["episodes"] - cell["errors"]
    dists = []
    for mean, sd in cell["final_distance_cm"]:
        if mean is None:
            dists.append("-")
        else:
            dists.append(f"{mean:.1f}" if cell["successes"] <= 1 else f"{mean:.1f}+-{sd:.1f}")
    return f"{cell['successes']}/{valid}", f"{cell['collision_free']}/{valid}", ", ".join(dists)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("results", nargs="+")
    parser.add_argument("--wall", type=float, help="wall time of the run [s]")
    parser.add_argument("--out", default=str(Path(__file__).with_name("results.md")))
    args = parser.parse_args()
    docs = [json.loads(Path(path).read_text()) for path in args.results]
    doc = docs[0]
    cells = {(c["env_id"], c["controller"], c["map"], c["slip"]): c for d in docs for c in d["cells"]}
    lines = ["# Paper protocol results", "",
             "Produced by `python evaluate.py --paper --out results_paper` (SPEC section 5: 3 robots, 10 trials per "
             "cell, trial i seeded i, the same slip draws for every controller), "
             "`python evaluate.py --paper --controllers rl-ppo --out results_rl` and "
             "`python docs/make_results_md.py results_paper/results.json results_rl/results.json`; "
             f"package {doc['package_version']}.",
             ""]  # fmt: skip
    if args.wall:
        lines += [f"Wall time of the run on the 2-core project machine: {args.wall:.0f} s ({args.wall / 60:.1f} min).", ""]
    lines += ["*Success*: every robot settled within 0.1 m of its target for 2 s without collision. *SR*: the paper's "
              "success rate (runs without collision). Distances: final distance per robot [cm], mean+-SD over the "
              "successful runs. The paper's column gives its SR and mean final distances; its maps are not published, "
              "so ours are our own designs (SPEC section 5) and only the shape of the results is comparable.", ""]  # fmt: skip
    for title, env_id, controller in TABLES:
        rows = [k for k in cells if k[0] == env_id and k[1] == controller]
        if not rows:
            continue
        lines += [f"## {title}", "", "| Map | Slip | Success | SR | Final distance [cm] (robots 1-3) | Paper: SR (distances) |",
                  "|---|---|---|---|---|---|"]  # fmt: skip
        for key in rows:
            success, sr, dist = fmt(cells[key])
            paper = PAPER.get((controller, key[2]), {}).get(key[3], "-")
            lines.append(f"| {key[2]} | {key[3]} | {success} | {sr} | {dist} | {paper} |")
        lines.append("")
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
