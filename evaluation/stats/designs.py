"""The designs of a suite run's paired tables: which comparisons a family holds, declared from the
run's header or its records before any outcome is read (:mod:`evaluation.stats.suite_statistics`
tests them).

- :func:`declared_pairs`: every two controllers of every task (:data:`EVERY_PAIR`);
- :func:`reference_pairs`: every controller against a reference within each task, and named pairs;
- :func:`pooled_reference_pairs`: the same pooled over the tasks (task :data:`ALL`): a comparison
  whose units are every task's, each (task, layout) a cluster of its own;
- :func:`tuned_pairs`, :func:`reference_design`, :func:`pooled_families`: the benchmark page's
  designs (docs/bench_results.md): each controller against a reference, with what tuning gained;
- :func:`pair_label`: a comparison's label in its family;
- :func:`table_power`: the power statement under a table of paired tests whose pairs are each a
  cluster of their own (the paper protocol's episodes, a sweep's units).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from controllers.tuning import V0_SUFFIX
from evaluation.stats.families import _check_power, _fewest_layouts, detectable_difference
from evaluation.stats.layout_tests import found_clause, holm_clause
from evaluation.stats.statistics import _check_confidence
from koopman_envs.checks import check_choice, check_int

__all__ = [
    "ALL",
    "EVERY_PAIR",
    "declared_pairs",
    "pair_label",
    "pooled_families",
    "pooled_reference_pairs",
    "reference_design",
    "reference_pairs",
    "tuned_pairs",
    "TablePower",
    "table_power",
]

#: a design: its pairs (task, a, b) and the clause that names it on a page
Design = tuple[list[tuple[str, str, str]], str]

#: the task of a comparison pooled over every task of the run (:func:`pooled_reference_pairs`), as
#: its rows and its label in the family name it
ALL = "both tasks"

#: the design of :func:`declared_pairs`, as a family's name states it
EVERY_PAIR = "every pair of controllers within each task"


def declared_pairs(records: Sequence[Mapping[str, Any]]) -> list[tuple[str, str, str]]:
    """The run's design: (task, a, b) for every two controllers of every task, in the order they
    first appear among the records (episodes that raised included: the design, not the outcomes)."""
    names: dict[str, dict[str, None]] = {}
    for record in records:
        names.setdefault(record["env_id"], {})[record["controller"]] = None
    return [
        (env_id, a, b)
        for env_id, labels in names.items()
        for i, a in enumerate(labels)
        for b in list(labels)[i + 1 :]
    ]


def reference_pairs(
    controllers: Mapping[str, Sequence[str]], reference: str, also: Sequence[tuple[str, str]] = ()
) -> list[tuple[str, str, str]]:
    """A design narrower than :func:`declared_pairs`, read from a run's declared controllers (its
    header), never from its outcomes: per task, (task, a, ``reference``) for every other
    controller a, in their order, then (task, a, b) for each (a, b) of ``also`` that the task has
    both of.

    Parameters
    ----------
    controllers : mapping of str to sequence of str
        Task (env id) -> the labels the run declares for it.
    reference : str
        The controller every other one is compared with (``b`` of its pairs).
    also : sequence of (str, str)
        Further pairs (a, b) the family holds, e.g. a tuned controller and its ``-v0``.

    Raises
    ------
    ValueError
        ``reference`` is not declared for some task (naming the task and its controllers).
    """
    pairs = []
    for env_id, labels in controllers.items():
        check_choice("reference", reference, labels, f" of {env_id}", among="the controllers")
        pairs += [(env_id, a, reference) for a in labels if a != reference]
        pairs += [(env_id, a, b) for a, b in also if a in labels and b in labels]
    return list(dict.fromkeys(pairs))


def pooled_reference_pairs(
    controllers: Mapping[str, Sequence[str]], reference: str, also: Sequence[tuple[str, str]] = ()
) -> list[tuple[str, str, str]]:
    """A design pooled over the tasks, read from a run's declared controllers (its header), never
    from its outcomes: (:data:`ALL`, a, ``reference``) for every other controller a declared in
    every task, in the first task's order, then (:data:`ALL`, a, b) for each (a, b) of ``also``
    declared in every task. :func:`measure_table` compares such a pair on the units of every task,
    each (task, layout) its own cluster.

    Parameters
    ----------
    controllers : mapping of str to sequence of str
        Task (env id) -> the labels the run declares for it (at least two tasks).
    reference : str
        The controller every other one is compared with (``b`` of its pairs).
    also : sequence of (str, str)
        Further pairs (a, b), e.g. a tuned controller and its ``-v0``.

    Raises
    ------
    ValueError
        Fewer than two tasks, or ``reference`` not declared for some task (naming the task and its
        controllers).
    """
    if len(controllers) < 2:
        raise ValueError(
            f"controllers declares the tasks {sorted(controllers)}; a pooled comparison needs at least two"
        )
    for env_id, labels in controllers.items():
        check_choice("reference", reference, labels, f" of {env_id}", among="the controllers")
    everywhere = [a for a in next(iter(controllers.values())) if all(a in c for c in controllers.values())]
    pairs = [(ALL, a, reference) for a in everywhere if a != reference]
    pairs += [(ALL, a, b) for a, b in also if a in everywhere and b in everywhere]
    return list(dict.fromkeys(pairs))


def pair_label(env_id: str, a: str, b: str) -> str:
    """A comparison's label in its family: ``<task id>: <a> vs <b>``."""
    return f"{env_id}: {a} vs {b}"


def tuned_pairs(labels: Sequence[str]) -> list[tuple[str, str]]:
    """The (tuned controller, its ``-v0``) pairs of ``labels`` that hold both: what tuning gained.

    Parameters
    ----------
    labels : sequence of str
        A run's controller labels.

    Returns
    -------
    list of (str, str)
        (``NAME``, ``NAME-v0``) for each ``NAME-v0`` of ``labels`` whose ``NAME`` is there too, in
        the order of the ``-v0`` labels.
    """
    tuned = [(label.removesuffix(V0_SUFFIX), label) for label in labels if label.endswith(V0_SUFFIX)]
    return [(a, b) for a, b in tuned if a in labels]


def reference_design(declared: Mapping[str, Sequence[str]], reference: str) -> Design:
    """The benchmark page's design for a run's per-task paired tables, read from its header before
    any outcome (:func:`reference_pairs`): every controller against ``reference``, and each tuned
    controller against its ``-v0`` (:func:`tuned_pairs`) where the run has both.

    Parameters
    ----------
    declared : mapping of str to sequence of str
        Task (env id) -> the labels the run declares for it.
    reference : str
        The controller every other one is compared with.

    Returns
    -------
    (list of (str, str, str), str)
        The pairs and the clause that names the design.

    Raises
    ------
    ValueError
        ``reference`` is not declared for some task.
    """
    labels = list(dict.fromkeys(label for names in declared.values() for label in names))
    tuned = tuned_pairs(labels)
    pairs = reference_pairs(declared, reference, tuned)
    design = f"each controller against {reference} within each task"
    if tuned:
        design += (
            ", and each tuned controller against its defaults before tuning ("
            + ", ".join(f"{a} vs {b}" for a, b in tuned)
            + ": what tuning gained)"
        )
    return pairs, design


def pooled_families(declared: Mapping[str, Sequence[str]], reference: str) -> list[Design]:
    """The headline families of a run declaring ``declared``, success pooled over both tasks
    (:func:`pooled_reference_pairs`): first the headline, every controller declared in both tasks
    against ``reference``; then, where the run has tuned controllers and their ``-v0``, what tuning
    gained as a family of its own (another question, kept out of the headline's m).

    Parameters
    ----------
    declared : mapping of str to sequence of str
        Task (env id) -> the labels the run declares for it (its header).
    reference : str
        The controller every other one is compared with.

    Returns
    -------
    list of (list of (str, str, str), str)
        Each family's pairs and the clause that names it; empty for fewer than two tasks.
    """
    if len(declared) < 2:
        return []
    labels = list(dict.fromkeys(label for labels in declared.values() for label in labels))
    against = pooled_reference_pairs(declared, reference)
    families = [(against, f"each controller against {reference} over both tasks")]
    tuned = [p for p in pooled_reference_pairs(declared, reference, tuned_pairs(labels)) if p not in against]
    if tuned:
        clause = ", ".join(f"{a} vs {b}" for _, a, b in tuned)
        families.append((tuned, f"each tuned controller against its defaults over both tasks ({clause})"))
    return families


@dataclass(frozen=True)
class TablePower:
    """What a table of paired success tests on independent units can detect (units that are
    their own clusters: the paper protocol's (map, slip, seed) episodes, a sweep's episode units),
    stated below the table as :class:`PowerStatement` states a clustered table's.

    Attributes
    ----------
    family_size : int
        ``m``, the distinct tests of the family the table's Holm adjustment runs over (it may
        span more tables than this one: a sweep's every paired test).
    alpha, alpha_per_test : float
        The family-wise level and Holm's first step, ``alpha / m``.
    comparisons : int
        The table's comparisons the discordance is pooled over.
    pairs, most_pairs : int
        The fewest pairs (units) any of them has (the design the power is computed for) and the most.
    total_pairs, discordant : int
        The pairs of all of them and the discordant ones among those (one side succeeded alone).
    unit : str
        What one pair is, in words (e.g. ``"one map, slip level and seed of the paper protocol"``).
    power, difference : float
        The smallest paired success difference found with probability ``power`` after Holm's
        first step at the pooled discordance (NaN: none).
    """

    family_size: int
    alpha: float
    alpha_per_test: float
    comparisons: int
    pairs: int
    most_pairs: int
    total_pairs: int
    discordant: int
    unit: str
    power: float
    difference: float

    @property
    def discordance(self) -> float:
        """The pooled discordance, discordant pairs over all pairs of the table's comparisons."""
        return self.discordant / self.total_pairs

    def sentence(self) -> str:
        """The statement in words, in the bench page's wording (:meth:`PowerStatement.sentence`)."""
        found = found_clause(
            self.difference,
            self.pairs,
            "pairs",
            _fewest_layouts(self.alpha_per_test),
            spread_is_zero=self.discordant == 0,
        )
        per = "pairs per comparison" + (
            " (the fewest of the table's)" if self.most_pairs > self.pairs else ""
        )
        return (
            f"Power: m = {self.family_size} test{'s' if self.family_size != 1 else ''}, "
            f"{holm_clause(self.alpha, self.alpha_per_test)}. With {self.pairs} {per}, a pair being "
            f"{self.unit}, and discordance {self.discordance:.2f} pooled over the table's "
            f"{self.comparisons} comparison{'s' if self.comparisons != 1 else ''} "
            f"({self.discordant:,} discordant of {self.total_pairs:,} pairs), "
            f"{found} is found with {100 * self.power:.0f}% power."
        )


def table_power(
    pairs: Sequence[int],
    discordant: Sequence[int],
    family_size: int,
    unit: str,
    *,
    alpha: float = 0.05,
    power: float = 0.8,
) -> TablePower:
    """The power statement of a table of paired success tests on unclustered units.

    Each pair is its own cluster (:func:`detectable_difference` with ``layouts`` the pairs and one
    unit per layout: the sign-flip test on the pairs' differences, i.e. the exact McNemar test's
    normal approximation). The design is the table's least favourable comparison's (the fewest
    pairs); the discordance is pooled over the table's comparisons (their discordant pairs over
    all their pairs), so a comparison with more pairs weighs more.

    Parameters
    ----------
    pairs : sequence of int
        Each comparison's pairs ``n`` (``>= 1``).
    discordant : sequence of int
        Each comparison's discordant pairs, ``only_a + only_b`` (within [0, n]).
    family_size : int
        ``m``, the distinct tests Holm's adjustment runs over, ``>= 1``: more than the table's
        comparisons when the family spans other tables (a sweep's every axis), fewer when a
        bit-identical twin's test is counted once.
    unit : str
        What one pair is, in words, for the sentence.
    alpha : float, optional
        Family-wise level, ``0 < alpha < 1``.
    power : float, optional
        Within [0.5, 1).

    Raises
    ------
    ValueError
        No comparison, lengths that differ, a count out of range, or an empty ``unit``.
    """
    power = _check_power(power)
    alpha = _check_confidence(alpha, "alpha")
    m = check_int("family_size", family_size, 1)
    ns, ds = list(pairs), list(discordant)
    if not ns:
        raise ValueError("pairs is empty; a table's power statement needs its comparisons")
    if len(ns) != len(ds):
        raise ValueError(
            f"pairs has {len(ns)} comparison(s) and discordant {len(ds)}; give one of each per comparison"
        )
    for index, (n, d) in enumerate(zip(ns, ds, strict=True)):
        check_int(f"pairs[{index}]", n, 1)
        check_int(f"discordant[{index}]", d, 0)
        if d > n:
            raise ValueError(
                f"discordant[{index}]={d} is more than pairs[{index}]={n}; it is at most the pairs"
            )
    if not isinstance(unit, str) or not unit:
        raise ValueError(f"unit={unit!r} must say what one pair is (a non-empty string)")
    total, discord = sum(ns), sum(ds)
    fewest = min(ns)
    difference = math.nan
    if discord > 0:
        difference = detectable_difference(
            fewest, 1, discordance=discord / total, family_size=m, alpha=alpha, power=power
        )
    return TablePower(m, alpha, alpha / m, len(ns), fewest, max(ns), total, discord, unit, power, difference)
