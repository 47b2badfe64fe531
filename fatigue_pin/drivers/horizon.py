"""How a problem is run over time: the horizon settings of a study (its ``[horizon]`` table).

Three drivers answer three questions:

* ``full``: one NLP over ``cycles`` cycles (:func:`fatigue_pin.drivers.full.solve_full`);
* ``sliding``: windows of ``cycles`` cycles advancing ``advance`` cycles at a time until one fails
  (:class:`fatigue_pin.drivers.sliding.SlidingHorizon`);
* ``max-cycles``: the largest number of cycles whose full horizon converges
  (:func:`fatigue_pin.drivers.full.max_repetitions`), up to ``max_cycles``.

:class:`Horizon` owns the keys every kind reads (``kind``, ``cycles``, ``cyclic_end``, ``guess``);
the other keys are the fields of :class:`~fatigue_pin.drivers.sliding.SlidingSettings` but its
``window`` (which is ``cycles``), so a field added there is a key of the table too. Two of them serve
the other kinds as well: ``max_cycles`` bounds the search of ``max-cycles``, ``end_tolerance`` is
the end box of a full horizon with ``cyclic_end``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.core.settings import check_fields, check_values, default_value, is_bool, is_int, setting
from fatigue_pin.drivers.sliding import SlidingSettings
from fatigue_pin.ocp.transcription import GUESSES

#: The horizon kinds (drivers) a study can run.
HORIZON_KINDS = ("full", "sliding", "max-cycles")

#: The field of SlidingSettings that Horizon states under another name.
_SLIDING_RENAMES = {"window": "cycles"}


def sliding_defaults() -> dict[str, Any]:
    """The sliding keys of a horizon table (SlidingSettings' fields but ``window``) and their defaults."""
    return {f.name: default_value(f) for f in dataclasses.fields(SlidingSettings) if f.name not in _SLIDING_RENAMES}


@dataclass(frozen=True)
class Horizon:
    """The horizon of a run (the ``[horizon]`` table of a study).

    Attributes:
        kind: ``full``, ``sliding`` or ``max-cycles`` (:data:`HORIZON_KINDS`).
        cycles: full: the horizon; sliding: the window (SlidingSettings' ``window``); not used by
            max-cycles.
        cyclic_end: full and max-cycles: also bound q and qdot at the last node to the initial
            state +- ``end_tolerance`` of their range (the sliding windows always have this box).
        guess: the first guess: ``rest``, ``physical`` or ``ik``
            (:meth:`fatigue_pin.ocp.transcription.Ocp.initial_guess`).
        sliding: the values of SlidingSettings' other fields by name (missing ones take their
            defaults). Each is checked alone for every kind; their relations to the window
            (``advance <= cycles``, ``max_cycles >= cycles``) only for ``sliding``.
    """

    kind: str = setting("full", "'full', 'sliding' or 'max-cycles'", lambda v: v in HORIZON_KINDS)
    cycles: int = setting(1, "an integer number of cycles >= 1", lambda v: is_int(v) and v >= 1)
    cyclic_end: bool = setting(False, "true or false", is_bool)
    guess: str = setting("rest", "'rest', 'physical' or 'ik'", lambda v: v in GUESSES)
    sliding: dict[str, Any] = setting(default_factory=dict, expected="values of the fields of SlidingSettings but window",
                                      check=lambda v: isinstance(v, dict), keys_of=(SlidingSettings, _SLIDING_RENAMES))

    def __post_init__(self) -> None:
        check_fields(self)
        values = sliding_defaults()
        for name in self.sliding:
            if name not in values:
                raise ParameterError(f"Horizon.sliding: unknown setting {name!r}; expected one of {sorted(values)}")
        values.update(self.sliding)
        check_values(SlidingSettings, values)
        object.__setattr__(self, "sliding", values)
        if values["heat_budget"] and self.kind != "sliding":
            raise ParameterError(f"horizon.heat_budget = true: expected horizon.kind = \"sliding\" (a budget for windows); "
                                 f"the kind is {self.kind!r}")
        if self.kind == "sliding":
            self.sliding_settings()  # the relations between the window and the other keys

    def sliding_settings(self) -> SlidingSettings:
        """The settings of the sliding-horizon driver (window = ``cycles``)."""
        return SlidingSettings(window=self.cycles, **self.sliding)

    @property
    def max_cycles(self) -> int | None:
        """sliding: stop once this many cycles are kept; max-cycles: the largest N tried (None: no bound)."""
        return self.sliding["max_cycles"]

    @property
    def end_tolerance(self) -> float:
        """The end box of the sliding windows, and of full horizons with ``cyclic_end`` (fraction of the ranges)."""
        return self.sliding["end_tolerance"]

    @property
    def end_box(self) -> float | None:
        """The end box of a full horizon (``end_tolerance`` with ``cyclic_end``, else None)."""
        return self.end_tolerance if self.cyclic_end else None

    @property
    def run_prefix(self) -> str:
        """The first part of run names: ``full`` (full horizons and the search of max-cycles) or ``sliding``."""
        return "sliding" if self.kind == "sliding" else "full"
