"""Named motor parameter sets, each with its source, and stand-in sets for the UR5 and the Panda.

``motor_preset(name, **overrides)`` returns a :class:`~fatigue_pin.motors.motor.MotorParameters`;
``MOTOR_PRESETS`` maps every name to a :class:`MotorPreset` ``(values, nominal current, source)``.

Datasheet sets (docs/motors.md has the table and the checks):

* ``maxon-re40``: maxon RE 40, 150 W, 48 V, #148877, as the PR2's production parameters give it
  (``PR2/pr2_ethercat_drivers``, ``ethercat_hardware/actuators.conf``, citing the maxon PDF):
  R 1.16 ohm, k_t 60.3 mN m/A, I_N 3.12 A, R_wh 1.93, R_ha 4.65 K/W, tau_w 41.6 s, tau_m 1120 s,
  T_max 155 deg C; gear 63.16 (the PR2 shoulder pan). No-load loss not known (speed not known): 0.
* ``maxon-re30``: maxon RE 30, 48 V, #310009, maxon's product page (2016) as transcribed: R 2.45
  ohm, k_t 53.8 mN m/A, I_N 1.74 A, R_wh 1.7, R_ha 6.0 K/W, tau_w 16.9 s, tau_m 593 s, T_max
  125 deg C, no-load loss at nominal speed I_0 k_t omega_N = 3.4 W; gear 60 (about the PR2 wrist).
* ``maxon-ec45flat``: maxon EC 45 flat, 70 W, 24 V, new generation (#651614 family), catalogue
  "motor data (provisional)": R 0.573 ohm, k_t 40.4 mN m/A, I_N 3.29 A, R_wh 6.64, R_ha 2.55 K/W,
  tau_w 43.1 s, tau_m 127 s, T_max 125 deg C, no-load loss 5.4 W; gear 100 (harmonic drive).

The no-load loss is the datasheet's at nominal speed, held constant: an arm's motors turn slower,
so this over-estimates the housing's heat (conservative).

Stand-ins (``ur5/size3``, ``ur5/size1``, ``panda/large``, ``panda/small``): no thermal data is
published for the UR5 or the Panda. Each stand-in keeps a datasheet motor's thermal network
(RE 40 for the large joints, EC 45 flat for the wrists), takes a gear of 101 (UR's widely reported
strain-wave ratio, unverified; 100 for the Panda, whose ratio is not published), and scales the
terminal resistance (:func:`scaled_to`) so that the continuous joint torque at 25 deg C with the
10 K margin is one third of the published peak torque (UR 150 / 28 N m, Panda 87 / 12 N m). The
one-third rule is our assumption; replace a stand-in by a fit (``fatigue-pin calibrate-thermal``)
when logged temperatures are at hand.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import NamedTuple

from fatigue_pin.core.errors import ParameterError, PresetFileError
from fatigue_pin.motors.motor import MotorParameters

__all__ = ["MotorPreset", "MOTOR_PRESETS", "ROBOT_MOTORS", "motor_preset", "load_motor_json", "scaled_to"]


class MotorPreset(NamedTuple):
    """A named motor parameter set.

    Attributes:
        values: the fields of :class:`MotorParameters` by name.
        nominal_current: the datasheet's nominal (continuous) current (A), None for a stand-in.
        source: where the values come from.
    """

    values: Mapping[str, float]
    nominal_current: float | None
    source: str


_RE40 = {"R25": 1.16, "k_t": 0.0603, "gear_ratio": 63.16, "R_wh": 1.93, "R_ha": 4.65, "tau_w": 41.6,
         "tau_m": 1120.0, "T_max": 155.0, "no_load_loss": 0.0}
_RE30 = {"R25": 2.45, "k_t": 0.0538, "gear_ratio": 60.0, "R_wh": 1.7, "R_ha": 6.0, "tau_w": 16.9,
         "tau_m": 593.0, "T_max": 125.0, "no_load_loss": 3.4}
_EC45 = {"R25": 0.573, "k_t": 0.0404, "gear_ratio": 100.0, "R_wh": 6.64, "R_ha": 2.55, "tau_w": 43.1,
         "tau_m": 127.0, "T_max": 125.0, "no_load_loss": 5.4}


def scaled_to(motor: MotorParameters, continuous_torque: float) -> MotorParameters:
    """``motor`` with its terminal resistance scaled so that its continuous joint torque
    (:meth:`MotorParameters.continuous_torque`) is ``continuous_torque`` (N m, > 0): the
    continuous current goes with ``1 / sqrt(R25)``, so ``R25`` is multiplied by the squared ratio."""
    now = motor.continuous_torque()
    if not (continuous_torque > 0 and now > 0):
        raise ParameterError(f"scaled_to continuous_torque = {continuous_torque!r}: expected a torque > 0 (N m) "
                             "and a motor with a continuous torque > 0")
    return dataclasses.replace(motor, R25=motor.R25 * (now / continuous_torque) ** 2)


def _stand_in(base: Mapping[str, float], gear: float, peak: float) -> dict[str, float]:
    motor = scaled_to(MotorParameters(**{**base, "gear_ratio": gear}), peak / 3.0)
    return {f.name: getattr(motor, f.name) for f in dataclasses.fields(motor)}


def _build() -> dict[str, MotorPreset]:
    out = {
        "maxon-re40": MotorPreset(_RE40, 3.12, "maxon RE 40 #148877 (PR2 actuators.conf); gear: PR2 shoulder pan"),
        "maxon-re30": MotorPreset(_RE30, 1.74, "maxon RE 30 #310009 (maxon product page 2016, transcribed); "
                                               "no-load loss 3.4 W at nominal speed"),
        "maxon-ec45flat": MotorPreset(_EC45, 3.29, "maxon EC 45 flat 70 W 24 V new generation (catalogue, provisional)"),
    }
    rule = ("stand-in: {motor} thermal network, gear {gear:g}, R25 scaled to a continuous torque of one third "
            "of the published peak {peak:g} N m (no thermal data published)")
    for name, base, motor, gear, peak in (("ur5/size3", _RE40, "RE 40", 101.0, 150.0),
                                          ("ur5/size1", _EC45, "EC 45 flat", 101.0, 28.0),
                                          ("panda/large", _RE40, "RE 40", 100.0, 87.0),
                                          ("panda/small", _EC45, "EC 45 flat", 100.0, 12.0)):
        out[name] = MotorPreset(_stand_in(base, gear, peak), None, rule.format(motor=motor, gear=gear, peak=peak))
    return out


#: Every named motor set.
MOTOR_PRESETS: Mapping[str, MotorPreset] = MappingProxyType(_build())

#: The stand-in motor of each joint of the robots in ``urdf/``, in joint order.
ROBOT_MOTORS: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "ur5": ("ur5/size3",) * 3 + ("ur5/size1",) * 3,
    "panda": ("panda/large",) * 4 + ("panda/small",) * 3,
})


def load_motor_json(path: str | Path) -> dict[str, float]:
    """The motor fields of a JSON file written by ``fatigue-pin calibrate-thermal`` (its ``motor``
    table), unchecked (:func:`motor_preset` checks them).

    Raises:
        PresetFileError: a file that is missing, not JSON, or without a ``motor`` table.
    """
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PresetFileError(f"motor file {str(p)!r} cannot be read as JSON ({exc}): expected the output of "
                              "fatigue-pin calibrate-thermal") from None
    motor = data.get("motor") if isinstance(data, dict) else None
    if not isinstance(motor, dict):
        raise PresetFileError(f"motor file {str(p)!r} has no 'motor' table: expected the output of fatigue-pin calibrate-thermal")
    return motor


def motor_preset(name: str, **overrides: float) -> MotorParameters:
    """The motor of preset ``name`` (a key of :data:`MOTOR_PRESETS`, or a ``.json`` file written by
    ``fatigue-pin calibrate-thermal``) with ``overrides`` of its fields (e.g. ``gear_ratio=80``,
    ``T_ambient=35``).

    Raises:
        ParameterError: unknown name, unknown field or a bad value (PresetFileError: a bad file).
    """
    if name.endswith(".json"):
        values = load_motor_json(name)
    elif name in MOTOR_PRESETS:
        values = dict(MOTOR_PRESETS[name].values)
    else:
        raise ParameterError(f"motor preset {name!r}: expected one of {sorted(MOTOR_PRESETS)} or a .json file "
                             "of fatigue-pin calibrate-thermal")
    fields = {f.name for f in dataclasses.fields(MotorParameters)}
    unknown = sorted((set(overrides) | set(values)) - fields)
    if unknown:
        raise ParameterError(f"motor preset {name!r}: unknown field {unknown[0]!r}; expected one of {sorted(fields)}")
    return MotorParameters(**{**values, **overrides})
