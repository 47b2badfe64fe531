"""The muscles of a model and the wrap cylinders their paths go round."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from fatigue_pin.core.errors import ParameterError
from fatigue_pin.muscles.muscle import Muscle
from fatigue_pin.muscles.wraps import CylinderWrap

__all__ = ["MuscleSet"]


@dataclass(frozen=True)
class MuscleSet:
    """Muscles (in their order: the order of every per-muscle vector) and wrap cylinders.

    Attributes:
        muscles: at least one, names unique.
        wraps: the cylinders, names unique; every name a muscle lists is one of them.
        source: where the set was read from (for messages), or ``""``.
        text: the muscle file's text it was read from (runs store it, so that verify rebuilds
            the muscles a run was solved with), or ``""`` (built in Python).
    """

    muscles: tuple[Muscle, ...]
    wraps: tuple[CylinderWrap, ...] = ()
    source: str = ""
    text: str = field(default="", repr=False, compare=False)

    def __post_init__(self) -> None:
        muscles, wraps = tuple(self.muscles), tuple(self.wraps)
        where = f" in {self.source}" if self.source else ""
        if not muscles:
            raise ParameterError(f"no muscles{where}: expected at least one")
        for kind, items in (("muscle", muscles), ("wrap", wraps)):
            names = [x.name for x in items]
            twice = sorted({n for n in names if names.count(n) > 1})
            if twice:
                raise ParameterError(f"{kind} {twice[0]!r} is defined twice{where}: expected unique names")
        known = {w.name for w in wraps}
        for m in muscles:
            for w in m.wraps:
                if w.name not in known:
                    raise ParameterError(f"muscle {m.name!r} wraps round {w.name!r}{where}, which is not a wrap of the set; "
                                         f"its wraps are {sorted(known)}")
        object.__setattr__(self, "muscles", muscles)
        object.__setattr__(self, "wraps", wraps)

    @property
    def names(self) -> tuple[str, ...]:
        """Muscle names, in order."""
        return tuple(m.name for m in self.muscles)

    def __len__(self) -> int:
        return len(self.muscles)

    def wrap(self, name: str) -> CylinderWrap:
        """The wrap cylinder ``name``."""
        for w in self.wraps:
            if w.name == name:
                return w
        raise ParameterError(f"unknown wrap {name!r}; the wraps are {[w.name for w in self.wraps]}")

    def without_wraps(self, names: Sequence[str] | None = None) -> MuscleSet:
        """The same muscles with the wraps ``names`` (default: all) dropped from every path."""
        drop = {w.name for w in self.wraps} if names is None else set(names)
        unknown = sorted(drop - {w.name for w in self.wraps})
        if unknown:
            raise ParameterError(f"unknown wrap {unknown[0]!r}; the wraps are {[w.name for w in self.wraps]}")
        import dataclasses

        muscles = tuple(dataclasses.replace(m, wraps=tuple(w for w in m.wraps if w.name not in drop)) for m in self.muscles)
        return MuscleSet(muscles, tuple(w for w in self.wraps if w.name not in drop), self.source)
