"""Every controller's options as one declarative spec: name, type, default, choices, doc.

``controllers.options("nominal-nmpc")`` returns the :class:`ControllerSpec` of a registered
controller, preset, wrapped configuration (``"safe:consensus"``) or import path. The spec is read
from the controller itself, so it cannot drift from it:

- names, defaults and types from the constructor's signature, or from the fields of the
  settings dataclass its ``**options`` fill: the class's ``SETTINGS`` (e.g.
  :class:`~controllers.classic.dwa.DWASettings`), else for the NMPCs
  :class:`~controllers.mpc.config.NMPCConfig`;
- docs from the ``Parameters`` section of the class docstring (a settings dataclass's:
  ``Attributes``);
- the allowed names of a text option from the ``OPTION_CHOICES`` table of the class (and of
  NMPCConfig), the range of a numeric one from its ``OPTION_RANGES`` table (NMPCConfig:
  :data:`~controllers.mpc.config.NMPC_RANGES`; a wrapper's option dataclass: ``RANGES``);
- a preset's defaults from :mod:`controllers.tuning.presets`, a ``safe:`` wrapper's options from
  :class:`~controllers.safety.options.SafetyOptions`, prefixed ``safety_``;
- the options the tuner searches (:mod:`evaluation.tune`), and over what, from the ``TUNABLE``
  table of the class (name -> :class:`Search`, each inside the option's declared range).

The evaluator asks the spec which configurations take ``solver`` and checks option names,
choices, types (a flag is true/false, a number is not a flag) and ranges before any controller
is built; ``python evaluate.py --options NAME`` prints it; the docs
page of controller options is generated from it (``docs/make_options_md.py``).
"""

from __future__ import annotations

import dataclasses
import inspect
import re
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from controllers.tuning.search_space import Search
from koopman_envs.checks import Range, check_choice, check_number, choice_message, did_you_mean

__all__ = ["ControllerSpec", "Option", "Search", "options", "spec_of", "with_search"]

_EMPTY = inspect.Parameter.empty


@dataclass(frozen=True)
class Option:
    """One option of a controller.

    Attributes
    ----------
    name : str
        As passed to ``controllers.make`` or written in ``name:key=value``.
    type : str
        The annotation as written in the code.
    default : object
        The default (``inspect.Parameter.empty`` for a required option).
    doc : str
        The docstring's text for it (first paragraph).
    choices : tuple of str, optional
        The allowed values of a text option.
    bounds : Range, optional
        The allowed range of a numeric option (of each entry of a tuple of numbers).
    search : Search, optional
        What the tuner tries for it (:mod:`evaluation.tune`); None: not tuned.
    """

    name: str
    type: str
    default: Any
    doc: str = ""
    choices: tuple[str, ...] | None = None
    bounds: Range | None = None
    search: Search | None = None

    @property
    def required(self) -> bool:
        """No default: the option must be given."""
        return self.default is _EMPTY

    @property
    def kind(self) -> str:
        """What the annotation asks for: ``"flag"``, ``"numbers"`` (a tuple), ``"number"``,
        ``"mapping"`` or ``""`` (anything else: text, paths, objects)."""
        words = {w.strip() for w in self.type.split("|")} - {"None"}
        if words == {"bool"}:
            return "flag"
        if any(w.startswith("tuple[") for w in words) and words <= {"tuple[float, ...]", "tuple[int, ...]"}:
            return "numbers"
        if words and words <= {"int", "float"}:
            return "number"
        if words and all(w.startswith("dict") for w in words):
            return "mapping"
        return ""

    def check(self, value: Any, owner: str) -> None:
        """Raise ``ValueError`` naming ``owner``, the option, the value and what is allowed when
        ``value`` is not one of :attr:`choices`, not of the option's kind (a flag takes
        true/false only, a number is never a flag, text or NaN, a dict option takes a dict), or
        outside :attr:`bounds`; None passes for an optional option (type ``... | None``)."""
        optional = "None" in self.type  # e.g. no fallback solver
        if value is None and optional:
            return
        also = " or None (null)" if optional else ""
        if self.choices is not None:
            check_choice(f"{owner}: {self.name}", value, self.choices, also)
        kind = self.kind
        if kind == "flag" and not isinstance(value, bool):
            raise ValueError(f"{owner}: {self.name}={value!r} is not a flag; allowed: true or false{also}")
        if kind == "mapping" and not isinstance(value, Mapping):
            raise ValueError(f"{owner}: {self.name}={value!r} is not a dict of options{also}")
        if kind not in ("number", "numbers"):
            return
        # without a declared range (a plugin's option) a number is at least a finite number
        check = self.bounds.check if self.bounds is not None else check_number
        try:
            if kind == "numbers":
                if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
                    raise ValueError(f"{self.name}={value!r} is not a list of numbers, each in {self.bounds}")
                for i, entry in enumerate(value):
                    check(f"{self.name}[{i}]", entry)
            else:
                check(self.name, value)
        except ValueError as exc:
            raise ValueError(f"{owner}: {exc}{also if kind == 'number' else ''}") from None


@dataclass(frozen=True)
class ControllerSpec:
    """The options of one controller configuration.

    Attributes
    ----------
    name : str
        The configuration's name (registered name, preset, ``safe:<name>`` or import path).
    doc : str
        First line of the controller's docstring.
    options : tuple of Option
        Every option it takes, in signature order (NMPC options after the controller's own).
    """

    name: str
    doc: str
    options: tuple[Option, ...]

    def names(self) -> list[str]:
        """The option names."""
        return [o.name for o in self.options]

    def takes(self, name: str) -> bool:
        """Whether the controller takes option ``name`` (e.g. ``"solver"``)."""
        return name in self.names()

    def option(self, name: str) -> Option:
        """One option by name (``KeyError`` naming the allowed ones)."""
        for o in self.options:
            if o.name == name:
                return o
        raise KeyError(f"{self.name} has no option {name!r}; it takes {self.names()}")

    def default(self, name: str) -> Any:
        """The default of option ``name``."""
        return self.option(name).default

    def tunable(self) -> dict[str, Search]:
        """The tuned options: name -> :class:`Search`, in signature order (empty: nothing to tune)."""
        return {o.name: o.search for o in self.options if o.search is not None}

    def check(self, given: Mapping[str, Any]) -> None:
        """Raise ``ValueError`` for an unknown option name (with did-you-mean) or a value outside
        an option's choices, before anything is built."""
        for key, value in given.items():
            if not self.takes(key):
                raise ValueError(
                    f"controller {self.name!r}: unknown option {key!r}{did_you_mean(key, self.names())}; "
                    f"it takes {self.names()}"
                )
            self.option(key).check(value, self.name)

    def markdown(self) -> str:
        """The options as a Markdown table (name, type, default, allowed, tuned over, doc)."""

        def cell(text: str) -> str:  # Markdown in a table cell: no pipes, no reST roles
            text = re.sub(r":[a-z]+:`~?([^`]+)`", r"`\1`", " ".join(text.split()))
            return text.replace("``", "`").replace("|", "\\|")

        rows = [
            "| option | type | default | allowed | tuned over | what it does |",
            "|---|---|---|---|---|---|",
        ]
        for o in self.options:
            default = "(required)" if o.required else cell(f"`{o.default!r}`")
            allowed = ", ".join(f"`{c}`" for c in o.choices) if o.choices else ""
            allowed = allowed or (cell(str(o.bounds)) if o.bounds is not None else "")
            tuned = cell(str(o.search)) if o.search is not None else ""
            rows.append(
                f"| `{o.name}` | {cell(f'`{o.type}`')} | {default} | {allowed} | {tuned} | {cell(o.doc)} |"
            )
        return "\n".join(rows)


def _sections(doc: str | None, heading: str) -> dict[str, str]:
    """name -> the first paragraph of its entry in section ``heading`` of a numpy-style docstring
    (``a, b : float`` gives both names the entry)."""
    lines = inspect.cleandoc(doc or "").splitlines()
    starts = [
        i for i in range(len(lines) - 1) if lines[i].strip() == heading and set(lines[i + 1].strip()) == {"-"}
    ]
    if not starts:
        return {}
    out: dict[str, str] = {}
    names: list[str] = []
    text: list[str] = []
    i = starts[0] + 2
    while i < len(lines):
        line = lines[i]
        if line and not line.startswith(" "):
            if i + 1 < len(lines) and set(lines[i + 1].strip()) == {"-"}:
                break  # the next section
            for name in names:
                out[name] = " ".join(text)
            names, text = [n.strip(" *") for n in line.split(" : ")[0].split(",")], []
        elif names and line.strip() and (not text or text[-1] != ""):
            text.append(line.strip())
        elif names and not line.strip() and text:
            text.append("")  # the end of the first paragraph: nothing more is taken
        i += 1
    for name in names:
        out[name] = " ".join(text)
    return {k: " ".join(v.split()) for k, v in out.items()}


def _from_signature(
    target: Callable[..., Any],
    docs: Mapping[str, str],
    choices: Mapping[str, Any],
    ranges: Mapping[str, Range],
) -> list[Option]:
    out = []
    for parameter in inspect.signature(target).parameters.values():
        if parameter.name in ("self", "config") or parameter.kind in (
            parameter.VAR_KEYWORD,
            parameter.VAR_POSITIONAL,
        ):
            continue
        annotation = parameter.annotation
        text = annotation if isinstance(annotation, str) else getattr(annotation, "__name__", str(annotation))
        allowed = choices.get(parameter.name)
        out.append(
            Option(
                parameter.name,
                "" if annotation is _EMPTY else text,
                parameter.default,
                docs.get(parameter.name, ""),
                tuple(allowed) if allowed is not None else None,
                ranges.get(parameter.name),
            )
        )
    return out


def _field_options(
    table: Any,
    choices: Mapping[str, Any],
    ranges: Mapping[str, Range],
    skip: Collection[str] = (),
    defaults: Mapping[str, Any] | None = None,
    prefix: str = "",
) -> list[Option]:
    """The fields of an options dataclass ``table`` as options named ``prefix + field``: docs
    from its ``Attributes`` section, ``defaults`` (the controller's own for some) over the
    fields' (None for a field without one), fields in ``skip`` left out."""
    docs = _sections(table.__doc__, "Attributes")
    given = defaults or {}
    return [
        Option(
            prefix + f.name,
            str(f.type),
            given.get(f.name, f.default if f.default is not dataclasses.MISSING else None),
            docs.get(f.name, ""),
            tuple(choices[f.name]) if f.name in choices else None,
            ranges.get(f.name),
        )
        for f in dataclasses.fields(table)
        if f.name not in skip
    ]


def _nmpc_options(skip: set[str], defaults: Mapping[str, Any]) -> list[Option]:
    """NMPCConfig's fields as options (``defaults``: the controller's own defaults for some)."""
    from controllers.mpc.config import NMPC_RANGES, NMPCConfig

    return _field_options(NMPCConfig, NMPCConfig.option_choices(), NMPC_RANGES, skip, defaults)


def spec_of(name: str, factory: Any) -> ControllerSpec:
    """The spec of the controller ``factory`` builds, registered as ``name``."""
    cls = factory if inspect.isclass(factory) else None
    target = cls.__init__ if cls is not None else factory
    doc_owner = cls if cls is not None else factory
    docs = _sections(getattr(doc_owner, "__doc__", None), "Parameters")
    choices = dict(getattr(cls, "OPTION_CHOICES", {}) or {})
    ranges = dict(getattr(cls, "OPTION_RANGES", {}) or {})
    found = _from_signature(target, docs, choices, ranges)
    signature = inspect.signature(target).parameters
    settings = getattr(cls, "SETTINGS", None)
    if settings is not None:  # **options are the fields of the class's settings dataclass
        found += _field_options(settings, choices, ranges, {o.name for o in found})
    elif "config" in signature and any(p.kind == p.VAR_KEYWORD for p in signature.values()):
        # **options are NMPCConfig's fields
        found += _nmpc_options({o.name for o in found}, getattr(cls, "NMPC_DEFAULTS", {}) or {})
    summary = inspect.cleandoc(getattr(doc_owner, "__doc__", "") or "").split("\n")[0]
    return with_search(ControllerSpec(name, summary, tuple(found)), getattr(cls, "TUNABLE", {}) or {})


def with_search(spec: ControllerSpec, tunable: Mapping[str, Search]) -> ControllerSpec:
    """``spec`` with the searches of ``tunable`` (a ``TUNABLE`` table) on its options.

    Raises
    ------
    ValueError
        A name of ``tunable`` that is not an option of ``spec``, or a search that leaves the
        option's declared range or choices (:meth:`Search.check_within`).
    """
    for key, search in tunable.items():
        option = spec.option(key) if spec.takes(key) else None
        if option is None:
            raise ValueError(
                choice_message(f"{spec.name}: TUNABLE key", key, spec.names(), sep=" ", among="its options")
            )
        search.check_within(f"{spec.name}: {key}", option.bounds, option.choices)
    changed = tuple(
        dataclasses.replace(o, search=tunable[o.name]) if o.name in tunable else o for o in spec.options
    )
    return ControllerSpec(spec.name, spec.doc, changed)


def _with_defaults(spec: ControllerSpec, name: str, defaults: Mapping[str, Any], doc: str) -> ControllerSpec:
    changed = tuple(
        dataclasses.replace(o, default=defaults[o.name]) if o.name in defaults else o for o in spec.options
    )
    return ControllerSpec(name, doc or spec.doc, changed)


def _wrapper_options(prefix: str) -> tuple[type, str, str]:
    """A wrapper prefix's option dataclass, the prefix of its options, and what it does, as the
    wrapper was registered (:func:`controllers.registry.register_wrapper`)."""
    from controllers.registry import wrapper_options

    found = wrapper_options(prefix)
    if found is None:
        raise ValueError(f"wrapper {prefix!r} was registered without an option class")
    return found


def options(name: str) -> ControllerSpec:
    """The options of a controller configuration (see the module docstring).

    Parameters
    ----------
    name : str
        A registered controller or preset, ``safe:<name>``, or ``package.module:Class``.

    Raises
    ------
    ValueError
        An unknown name (listing the available ones).
    """
    from controllers.registry import factory, split_name
    from controllers.tuning.presets import CONTROLLERS, PRESETS, _resolve

    prefixes, base = split_name(name)
    if prefixes:
        inner = options(name.split(":", 1)[1])
        table, prefix, role = _wrapper_options(prefixes[0])
        mine = tuple(_field_options(table, {}, getattr(table, "RANGES", {}), prefix=prefix))
        return ControllerSpec(name, f"{inner.doc} ({role})", inner.options + mine)
    presets = {p.name: p for p in PRESETS}
    if base in presets:
        preset = presets[base]
        # the preset's base as its class declares it (the preset's defaults alone stand over the
        # class's, as build_preset builds it: a tuned preset of the base is not inherited)
        spec = spec_of(preset.base, _resolve(CONTROLLERS[preset.base]))
        spec = with_search(_with_defaults(spec, base, preset.defaults, preset.doc), preset.tunable)
        if preset.untuned:  # no searches of its own, nor its base's (Preset.untuned says why)
            spec = ControllerSpec(
                spec.name, spec.doc, tuple(dataclasses.replace(o, search=None) for o in spec.options)
            )
        return spec
    if base in CONTROLLERS:
        return spec_of(base, _resolve(CONTROLLERS[base]))
    return spec_of(base, factory(base))
