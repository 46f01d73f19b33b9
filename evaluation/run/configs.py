"""Controller configurations: a registered controller plus options, as one leaderboard row.

On the command line a configuration is ``name`` or ``name:key=value,key=value`` (values parsed
as JSON scalars, else kept as text; ``label=...`` names the row, by default the text itself);
``name`` is a registered controller or the import path of a factory or class,
``package.module:Class``::

    nominal-nmpc   nominal-nmpc:solver=fatrop   koopman-nmpc:uncertainty_margin=0,horizon=30

A registered wrapper prefix comes first: ``safe:consensus-free`` is ``consensus-free`` behind the
CBF safety filter, and in ``safe:nominal-nmpc:horizon=10,safety_gamma=1`` the options prefixed
``safety_`` go to the filter, the others to ``nominal-nmpc`` (see :mod:`controllers.safety`).

Several configurations may also be given comma-separated in one word
(``nominal-nmpc,koopman-nmpc:horizon=30,consensus``): a piece with ``=`` and no ``:`` continues
the options of the configuration before it.

From Python, :func:`controller_configs` also takes a mapping from label to a registered name, a
``(name or factory, options)`` pair, or a factory / controller class of the user's own script,
which is then ranked beside the registered ones without packaging it.
"""

from __future__ import annotations

import json
import pickle
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import controllers
from controllers.registry import controller_class, declared_class, is_import_path, split_name
from controllers.registry import factory as registered_factory
from koopman_envs.checks import CLI_JSON_CHARS, check_choice, parse_json

__all__ = [
    "ControllerConfig",
    "check_label",
    "controller_configs",
    "parse_controller",
    "split_controller_list",
    "with_solver",
]

#: ``--fallback-solver`` value that turns every NMPC's NLP rescue off
FALLBACK_NONE = "none"


@dataclass(frozen=True)
class ControllerConfig:
    """A controller as the evaluator runs it.

    Attributes
    ----------
    label : str
        Row name in every report (unique within a run).
    name : str
        Registered controller name.
    options : tuple of (str, value)
        Keyword options of the factory, sorted by key (plain JSON values).
    factory : callable, optional
        A factory or controller class not in the registry (Python API); ``name`` is then its
        ``module.qualname``, recorded in the results.
    """

    label: str
    name: str
    options: tuple[tuple[str, Any], ...] = ()
    factory: Callable[..., Any] | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        check_label(self.label)

    def build(self) -> Any:
        """A fresh controller instance."""
        if self.factory is not None:
            return self.factory(**dict(self.options))
        return controllers.make(self.name, **dict(self.options))

    def controller_class(self, *, wrapped: bool = False) -> type | None:
        """The class this configuration builds, found without building it
        (:func:`controllers.registry.controller_class`), so that the evaluator can read what the
        class declares (``acts_in_batch``, ``episode_cost``); None when only a call would tell.

        ``wrapped``: the class of the controller behind the wrapper prefixes (``safe:``,
        ``ekf:``) rather than the outermost wrapper's.
        """
        if self.factory is not None:
            return declared_class(self.factory)
        return controller_class(split_name(self.name)[1] if wrapped else self.name)

    def validate(self, across_processes: bool = False) -> None:
        """Build once to reject unknown names and options before any episode starts.

        ``across_processes``: the factory must also reach worker processes (by reference: a
        module-level function or class).
        """
        if self.factory is not None:
            if across_processes:
                try:
                    pickle.loads(pickle.dumps(self.factory))
                except Exception as exc:  # noqa: BLE001 - any pickling problem has the same remedy
                    raise ValueError(
                        f"controller {self.label!r}: factory {self.name} cannot be sent to worker processes "
                        f"({type(exc).__name__}: {exc}); define it at module level or run with workers=1"
                    ) from None
        else:
            registered_factory(self.name)  # unknown names (also behind a wrapper prefix) raise ValueError
            # option names and text choices from the controller's spec, with did-you-mean; the
            # build below then checks the values the constructors check (ranges, types)
            from controllers.option_spec import options

            try:
                options(self.name).check(dict(self.options))
            except ValueError as exc:
                where = "" if self.label == self.name else f"controller {self.label!r}: "
                raise ValueError(f"{where}{exc}") from None
        try:
            self.build()
        except TypeError as exc:
            raise ValueError(
                f"controller {self.label!r}: bad option in {dict(self.options)} ({exc})"
            ) from None
        except ValueError as exc:
            raise ValueError(f"controller {self.label!r}: {exc}") from None

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON form (recorded in results)."""
        return {"label": self.label, "name": self.name, "options": dict(self.options)}


def check_label(label: Any) -> str:
    """``label`` if it can name a row of every report: non-empty text on one line, without control
    characters (a newline broke the results.md table); else ``ValueError`` naming it."""
    if not isinstance(label, str) or not label.strip():
        raise ValueError(f"controller label {label!r} must be non-empty text")
    if not label.isprintable():
        raise ValueError(
            f"controller label {label!r} holds a line break or another control character; a label is one line"
        )
    return label


def _scalar(key: str, text: str) -> Any:
    """Option ``key``'s value text as JSON (a scalar), else the text itself."""
    if text.strip() == "None":  # Python's spelling of JSON's null
        return None
    try:
        value = parse_json(text, f"option {key}", max_chars=CLI_JSON_CHARS)
    except json.JSONDecodeError:
        return text
    if isinstance(value, (list, dict)):
        raise ValueError(f"option {key}={text!r} must be a scalar (number, true/false, null or text)")
    return value


def parse_controller(text: str | ControllerConfig) -> ControllerConfig:
    """``name`` or ``name:key=value,...`` -> :class:`ControllerConfig` (``ValueError`` when malformed);
    ``name`` may start with wrapper prefixes (``safe:name:key=value``)."""
    if isinstance(text, ControllerConfig):
        return text
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"controller {text!r} must be a non-empty 'name' or 'name:key=value,...'")
    prefixes, base = split_name(text.strip())
    name, sep, rest = _name_and_options(base)
    name = ":".join([*prefixes, name.strip()])
    options: dict[str, Any] = {}
    label = text.strip()
    if sep:
        if not rest:
            raise ValueError(f"controller {text!r}: nothing after ':'; expected 'name:key=value,...'")
        given: set[str] = set()
        for item in rest.split(","):
            key, eq, value = item.partition("=")
            key = key.strip()
            if not eq or not key.isidentifier():
                raise ValueError(
                    f"controller {text!r}: {item!r} is not key=value (a Python identifier as key)"
                )
            if key in given:  # the last would win without a word
                raise ValueError(f"controller {text!r}: option {key!r} is given twice; give each option once")
            given.add(key)
            if key == "label":
                label = value.strip()
                if not label:
                    raise ValueError(
                        f"controller {text!r}: label= is empty; name the row or leave label= out"
                    )
            else:
                options[key] = _scalar(key, value.strip())
    return ControllerConfig(label, name.strip(), tuple(sorted(options.items())))


def _name_and_options(base: str) -> tuple[str, str, str]:
    """``base`` (no wrapper prefix) -> (name, ":" or "", options text); the name may be an
    import path ``package.module:Class``."""
    name, sep, rest = base.partition(":")
    attribute, attr_sep, after = rest.partition(":")
    if name not in controllers.available() and is_import_path(f"{name}:{attribute}"):
        return f"{name}:{attribute}", attr_sep, after
    return name, sep, rest


def _has_options(text: str) -> bool:
    return bool(_name_and_options(split_name(text)[1])[1])


def split_controller_list(words: Iterable[str]) -> list[str]:
    """Command-line words -> configuration texts, also splitting comma-separated lists.

    ``["nominal-nmpc,koopman-nmpc:horizon=30,uncertainty_margin=0", "consensus"]`` ->
    ``["nominal-nmpc", "koopman-nmpc:horizon=30,uncertainty_margin=0", "consensus"]``: a piece
    with ``=`` and without ``:`` continues the options of the configuration before it.
    """
    texts: list[str] = []
    for word in words:
        for piece in word.split(","):
            piece = piece.strip()
            if not piece:
                continue
            continues = "=" in piece and ":" not in piece.partition("=")[0]
            if continues and texts and _has_options(texts[-1]):
                texts[-1] += "," + piece
            elif continues:
                raise ValueError(
                    f"controller list {word!r}: option {piece!r} follows no 'name:' configuration"
                )
            else:
                texts.append(piece)
    return texts


def _qualified_name(factory: Callable[..., Any]) -> str:
    return f"{getattr(factory, '__module__', '?')}.{getattr(factory, '__qualname__', repr(factory))}"


def _from_entry(label: str, entry: Any) -> ControllerConfig:
    """One mapping entry -> configuration (``label`` names the row)."""
    if isinstance(entry, ControllerConfig):
        return ControllerConfig(label, entry.name, entry.options, entry.factory)
    if isinstance(entry, str):
        parsed = parse_controller(entry)
        return ControllerConfig(label, parsed.name, parsed.options)
    if callable(entry):
        return ControllerConfig(label, _qualified_name(entry), (), entry)
    if isinstance(entry, tuple) and len(entry) == 2 and isinstance(entry[1], Mapping):
        target, options = entry
        for key, value in options.items():
            if not isinstance(key, str) or not key.isidentifier():
                raise ValueError(f"controller {label!r}: option name {key!r} is not a Python identifier")
            try:
                json.dumps(value, allow_nan=False)
            except (TypeError, ValueError):
                raise ValueError(
                    f"controller {label!r}: option {key}={value!r} must be plain JSON "
                    "(it is recorded in the results)"
                ) from None
        ordered = tuple(sorted(options.items()))
        if isinstance(target, str):
            return ControllerConfig(label, target, ordered)
        if callable(target):
            return ControllerConfig(label, _qualified_name(target), ordered, target)
    raise ValueError(
        f"controller {label!r}: {entry!r} is not a registered name, 'name:key=value,...', a (name or factory, "
        "options dict) pair, or a factory / controller class"
    )


def controller_configs(spec: Any) -> list[ControllerConfig]:
    """Any accepted form of a run's controllers -> configurations (``ValueError`` when malformed).

    Parameters
    ----------
    spec : mapping or sequence
        A mapping ``{label: entry}`` where an entry is a registered name, a ``"name:key=value"``
        text, a ``(name or factory, {options})`` pair or a factory / controller class; or a
        sequence of texts, :class:`ControllerConfig` or factories (labelled by their text or
        ``module.qualname``).
    """
    if isinstance(spec, Mapping):
        for label in spec:
            if not isinstance(label, str) or not label.strip():
                raise ValueError(f"controller label {label!r} must be non-empty text")
        return [_from_entry(label, entry) for label, entry in spec.items()]
    if isinstance(spec, (str, bytes)) or not isinstance(spec, Iterable):
        raise ValueError(
            f"controllers={spec!r} must be a list of configurations or a mapping label -> controller"
        )
    configs = []
    for entry in spec:
        if isinstance(entry, (str, ControllerConfig)):
            configs.append(parse_controller(entry))
        elif callable(entry):
            configs.append(ControllerConfig(_qualified_name(entry), _qualified_name(entry), (), entry))
        else:
            raise ValueError(f"controller {entry!r} is not a configuration text, ControllerConfig or factory")
    return configs


def _spec(config: ControllerConfig) -> Any:
    """The option spec of the controller ``config`` names (nothing is built)."""
    from controllers.option_spec import options

    if config.factory is not None:
        from controllers.option_spec import spec_of

        return spec_of(config.label, config.factory)
    return options(config.name)


def _takes(config: ControllerConfig, option: str) -> bool:
    return bool(_spec(config).takes(option))


def _default_solver(config: ControllerConfig) -> str | None:
    """The default ``solver`` of the controller ``config`` names, or None when it takes no
    ``solver`` option."""
    spec = _spec(config)
    return str(spec.default("solver")) if spec.takes("solver") else None


def with_solver(
    configs: Iterable[ControllerConfig], solver: str | None, fallback_solver: str | None = None
) -> list[ControllerConfig]:
    """``configs`` with ``solver=`` set on every NMPC configuration (central or distributed) that
    does not set it itself and does not solve with it by default, and ``fallback_solver=`` on
    every one that does not set it itself.

    ``solver=None`` and ``fallback_solver=None`` change nothing; ``fallback_solver="none"`` turns
    the NLP rescue off (:class:`controllers.mpc.config.NMPCConfig`). A name outside
    :data:`controllers.mpc.config.SOLVERS` raises ``ValueError`` naming it and the allowed ones.
    """
    configs = list(configs)
    from controllers.mpc.config import NLP_SOLVERS, SOLVERS

    if solver is not None:
        check_choice("--solver", solver, SOLVERS, sep=" ")
    if fallback_solver is not None:
        check_choice("--fallback-solver", fallback_solver, [*NLP_SOLVERS, FALLBACK_NONE], sep=" ")
    out = []
    for config in configs:
        given = dict(config.options)
        changes: dict[str, Any] = {}
        # an NMPC that already solves with ``solver`` by default is left as it is (its
        # configuration, and so a baseline's, does not change)
        if solver is not None and "solver" not in given and _default_solver(config) not in (None, solver):
            changes["solver"] = solver
        rescue = None if fallback_solver == FALLBACK_NONE else fallback_solver
        # as for the solver: a configuration whose default it already is stays as it is
        if (
            fallback_solver is not None
            and "fallback_solver" not in given
            and _takes(config, "fallback_solver")
            and _spec(config).default("fallback_solver") != rescue
        ):
            changes["fallback_solver"] = rescue
        if changes:
            options = tuple(sorted((*config.options, *changes.items())))
            config = ControllerConfig(config.label, config.name, options, config.factory)
        out.append(config)
    return out
