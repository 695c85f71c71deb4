"""Typed, bounded options of the supervisor's algorithms: one schema mechanism for every plant kind.

An algorithm declares its options as a dataclass (usually the settings dataclass it already has); each field's
type says what a value must be, and a ``Bounds`` in its annotation says the physical range and unit::

    @dataclass(frozen=True)
    class MySettings:
        window: Annotated[int, Bounds(ge=1, le=1000, unit="ticks")] = 4
        rate: Annotated[float, Bounds(gt=0.0, le=1000.0, unit="1/1000 s")] = 0.01
        on: bool = True

``OptionSchema({"": MySettings})`` reads the fields from the dataclass itself, so a field added to the dataclass
is an option at once, with no second list to keep. Validation goes through pydantic: scalars are strict (a
string is not a number, 1 is not ``True``, 4.5 is not an integer), a sequence field takes a list, and bounds
apply to each element of a sequence. A prefix maps a second dataclass into the same flat namespace
(``{"": FDISettings, "component_": ComponentSettings}``: ``component_window`` is ``ComponentSettings.window``).
A pydantic ``BaseModel`` may stand in for a dataclass.
"""

from __future__ import annotations

import dataclasses
import functools
import operator
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from types import UnionType
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, Strict, ValidationError, create_model


@dataclass(frozen=True)
class Bounds:
    """Closed (``ge``, ``le``) or open (``gt``, ``lt``) limits of a numeric option, and its unit ("–" if none)."""

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    unit: str = "–"

    def text(self) -> str:
        """The range as a reader would write it: ``> 0 … ≤ 1000``."""
        low = f"≥ {self.ge:g}" if self.ge is not None else f"> {self.gt:g}" if self.gt is not None else ""
        high = f"≤ {self.le:g}" if self.le is not None else f"< {self.lt:g}" if self.lt is not None else ""
        return " … ".join(part for part in (low, high) if part) or "(any value)"


@dataclass(frozen=True)
class OptionInfo:
    """One declared option: its key, type, default, bounds and the dataclass field it comes from."""

    key: str
    type_text: str
    default: Any
    bounds: Bounds | None
    owner: str  # the declaring class


_SCALARS = (bool, int, float, str)


def _constrained(tp: Any, bounds: Bounds | None) -> Any:
    """``tp`` with strict scalars and ``bounds`` on every numeric element (tuples, lists, optionals)."""
    origin = typing.get_origin(tp)
    if origin is Annotated:  # Bounds become pydantic constraints; other metadata (a pydantic Field, …) is kept
        kept = tuple(m for m in tp.__metadata__ if not isinstance(m, Bounds))
        inner = _constrained(tp.__origin__, bounds)
        return Annotated[(inner, *kept)] if kept else inner
    if origin in (tuple, list):
        args = typing.get_args(tp)
        inner = tuple(a if a is Ellipsis else _constrained(a, bounds) for a in args)
        return tuple[inner] if origin is tuple else list[inner[0]]  # type: ignore[valid-type]
    if origin in (typing.Union, UnionType):
        return functools.reduce(operator.or_, [_constrained(a, bounds) for a in typing.get_args(tp)])
    if tp in _SCALARS:
        limits = {}
        if bounds is not None and tp in (int, float):
            limits = {k: getattr(bounds, k) for k in ("ge", "gt", "le", "lt") if getattr(bounds, k) is not None}
        return Annotated[tp, Strict(), Field(**limits)]
    return tp  # Literal, Enum, …: pydantic's own check


def _bounds_of(hint: Any) -> Bounds | None:
    if typing.get_origin(hint) is Annotated:
        return next((m for m in hint.__metadata__ if isinstance(m, Bounds)), None)
    return None


def _type_text(hint: Any) -> str:
    base = hint.__origin__ if typing.get_origin(hint) is Annotated else hint
    if isinstance(base, type) and typing.get_origin(base) is None:
        return base.__name__
    return str(base).replace("typing.", "")


def _fields(cls: type) -> list[tuple[str, Any, Any]]:
    """(name, annotation with extras, default) of a dataclass or a pydantic model."""
    if isinstance(cls, type) and issubclass(cls, BaseModel):
        return [
            (name, f.rebuild_annotation(), None if f.is_required() else f.get_default(call_default_factory=True))
            for name, f in cls.model_fields.items()
        ]
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"{cls!r}: options are declared by a dataclass or a pydantic model")
    hints = typing.get_type_hints(cls, include_extras=True)
    out = []
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            raise TypeError(f"{cls.__name__}.{f.name}: an option needs a default")
        out.append((f.name, hints[f.name], default))
    return out


class OptionSchema:
    """The options one algorithm accepts, from one or more dataclasses (prefix → class), validated by pydantic."""

    def __init__(self, parts: Mapping[str, type] | None = None):
        self.parts = dict(parts or {})
        self.options: dict[str, OptionInfo] = {}
        fields: dict[str, Any] = {}
        for prefix, cls in self.parts.items():
            for name, hint, default in _fields(cls):
                key = prefix + name
                if key in self.options:
                    raise TypeError(f"option {key!r} is declared twice ({cls.__name__})")
                bounds = _bounds_of(hint)
                self.options[key] = OptionInfo(key, _type_text(hint), default, bounds, cls.__name__)
                fields[key] = (_constrained(hint, bounds), default)
        self._model = create_model("Options", __config__=ConfigDict(extra="forbid"), **fields)

    @classmethod
    def of(cls, declared: OptionSchema | type | Mapping[str, type] | None) -> OptionSchema:
        """A schema from what ``Registry.register(options=…)`` accepts; ``None`` declares no option."""
        if isinstance(declared, OptionSchema):
            return declared
        if declared is None:
            return cls({})
        if isinstance(declared, Mapping):
            return cls(declared)
        return cls({"": declared})

    def keys(self) -> list[str]:
        return list(self.options)

    def validate(self, params: Mapping[str, Any]) -> tuple[dict[str, Any], list[tuple[str, str]]]:
        """The declared keys of ``params``, validated: (values as given but checked, problems as (key, message)).

        Keys this schema does not declare are left out (the caller decides whether another algorithm takes them).
        """
        mine = {k: v for k, v in params.items() if k in self.options}
        try:
            model = self._model.model_validate(mine)
        except ValidationError as error:
            return {}, [self._problem(e) for e in error.errors()]
        return {k: getattr(model, k) for k in mine}, []

    def _problem(self, err: Mapping[str, Any]) -> tuple[str, str]:
        """(key, "got 2.0: should be less than or equal to 1; accepts float ≥ 0 … ≤ 1 s") from a pydantic error."""
        loc = err["loc"]
        key = str(loc[0])
        where = key + "".join(f"[{part}]" for part in loc[1:] if isinstance(part, int))
        text = f"got {err.get('input')!r}: {err['msg'].replace('Input should', 'should')}"
        info = self.options.get(key)
        if info is not None:
            accepts = info.type_text
            if info.bounds is not None:
                unit = "" if info.bounds.unit == "–" else f" {info.bounds.unit}"
                accepts += f" {info.bounds.text()}{unit}"
            text += f"; accepts {accepts}"
        return where, text
