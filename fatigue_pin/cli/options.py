"""Options of the ``fatigue-pin`` commands whose default belongs to the package, not to the
command line: a setting of a settings class (:mod:`fatigue_pin.core.settings`) or an argument of a
function. Such an option is None unless given (:func:`option`); the help shows the owner's default,
read when the help is shown (:class:`DefaultsFormatter`), and a given value is checked by the
setting's own check, with a message naming the option (:func:`check_options`). The command line
thus holds no copy of a default.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import inspect
from typing import Any, Mapping

from fatigue_pin.core.errors import UsageError

__all__ = ["DefaultsFormatter", "check_options", "given", "option", "owner", "owner_default"]


def owner(target: str) -> Any:
    """The object ``target`` ("module:name") names (a settings class, a function, a constant)."""
    module, name = target.split(":")
    return getattr(importlib.import_module(module), name)


def owner_default(target: str, name: str | None) -> Any:
    """The default of setting ``name`` of the settings class, or of argument ``name`` of the
    function, ``target`` ("module:name"); with ``name`` None, the value ``target`` itself."""
    obj = owner(target)
    if name is None:
        return obj
    if dataclasses.is_dataclass(obj):
        from fatigue_pin.core.settings import default_of

        return default_of(obj, name)
    return inspect.signature(obj).parameters[name].default


def _shown(value: Any) -> str:
    """A default as the help shows it: ``none``, numbers with ``%g``, sequences comma-separated."""
    if value is None:
        return "none"
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (tuple, list)):
        return ",".join(_shown(v) for v in value)
    return str(value)


class DefaultsFormatter(argparse.HelpFormatter):
    """Help texts that end with the default of the setting an option stands for, read from its
    owner when the help is shown (so the command line holds no copy of it)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = super()._get_help_string(action)
        source = getattr(action, "default_from", None)
        if source is None:
            return text
        return f"{text} (default {_shown(owner_default(*source))})".replace("%", "%%")


def option(p: argparse.ArgumentParser, *flags: str, default_from: tuple[str, str | None], **kwargs: Any) -> None:
    """An option that is None unless given: its default is the one of ``default_from``
    (:func:`owner_default`), applied where the value is used."""
    action = p.add_argument(*flags, default=None, **kwargs)
    action.default_from = default_from  # type: ignore[attr-defined]


def given(args: argparse.Namespace, **names: str) -> dict[str, Any]:
    """The options of ``names`` (keyword -> option attribute) that were given on the line."""
    return {key: getattr(args, attr) for key, attr in names.items() if getattr(args, attr, None) is not None}


def check_options(args: argparse.Namespace, checked: Mapping[str, tuple[str, str]]) -> None:
    """Refuse a given option value that its setting's own check refuses, naming the option
    (``checked``: option attribute -> ("module:SettingsClass", setting))."""
    from fatigue_pin.core.settings import check_message, expected_of, field_of

    for attr, (target, name) in checked.items():
        value = getattr(args, attr, None)
        if value is not None:
            cls = owner(target)
            f = field_of(cls, name)
            if check_message(cls, f, value):
                raise UsageError(f"--{attr.replace('_', '-')} {value}: expected {expected_of(f)}")
