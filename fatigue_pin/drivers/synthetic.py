"""A synthetic run record of arm26's size, for tests and benchmarks of what reads and writes runs
(result files, plots, sweeps): random motion and controls, fatigue growing linearly; no solve.

:func:`synthetic_run` is the one builder (``tests/conftest.py``'s ``make_run`` and
``benchmarks/results_write.py`` use it). Its values are not a motion of the arm: they have the
shapes, names and attributes of a stored run, no more.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fatigue_pin.drivers.run import WINDOW_DTYPE, RunResult, torque_limits_at_cycle_ends

__all__ = ["synthetic_run"]

#: Signed torque limits of the four halves (N m): shoulder +-50, elbow +-50.
_LIMITS = np.array([50.0, -50.0, 50.0, -50.0])


def synthetic_run(name: str = "full/torque_S10", cycles: int = 2, n: int = 10, windows: int | None = None,
                  seed: int = 0, mf_end: float = 0.3, urdf: str = "<robot name='x'/>",
                  attrs: dict[str, Any] | None = None, joints: tuple[str, str] = ("shoulder", "elbow"),
                  joint_kinds: tuple[str, str] = ("revolute", "revolute")) -> RunResult:
    """A run of ``cycles`` cycles of ``n`` intervals (1 s each) on two joints and four halves.

    Args:
        name: the run's name (``full/...``, ``sliding/...``).
        cycles: cycles stored; n: intervals per cycle.
        windows: a sliding run's window table of that many converged windows (None: a full run).
        seed: the seed of the random q, qdot, torques, ma, mr and cycle costs.
        mf_end: every mf grows linearly from 0 to this at the last node.
        urdf: the URDF text stored with the run.
        attrs: attributes added to (or replacing) the run's own (horizon, cost, S, converged,
            n_cycles, tau_limits).
        joints: the names of its two joints (the halves are ``<joint>_plus``, ``<joint>_minus``).
        joint_kinds: the kinds of its two joints (``revolute``, ``prismatic``), which give their units.
    """
    nodes = cycles * n + 1
    rng = np.random.default_rng(seed)
    mf = np.linspace(0, mf_end, nodes)[:, None] * np.ones((1, 4))
    table = None
    if windows is not None:
        table = np.array([(i, i, b"Solve_Succeeded", True, 40, 0.3, 1.0) for i in range(windows)], dtype=WINDOW_DTYPE)
    base = {"horizon": "full" if windows is None else "sliding", "cost": "torque", "S": 10.0, "converged": True,
            "n_cycles": cycles, "tau_limits": _LIMITS.copy()}
    return RunResult(
        name=name,
        attrs={**base, **(attrs or {})},
        t=np.linspace(0, cycles, nodes),
        q=rng.normal(size=(nodes, 2)),
        qdot=rng.normal(size=(nodes, 2)),
        tau_plus=rng.uniform(0, 50, size=(nodes - 1, 2)),
        tau_minus=-rng.uniform(0, 50, size=(nodes - 1, 2)),
        fatigue={"ma": rng.uniform(size=(nodes, 4)), "mr": rng.uniform(size=(nodes, 4)), "mf": mf},
        cycle_costs=rng.uniform(size=(cycles, 4)),
        torque_limits=torque_limits_at_cycle_ends(mf, _LIMITS, n),
        fatigued=mf,
        joint_names=tuple(joints),
        joint_kinds=joint_kinds,
        actuator_names=tuple(f"{j}_{sign}" for j in joints for sign in ("plus", "minus")),
        cost_terms=("posture", "torque_rate", "fatigue", "torque"),
        cycle_wall_time_s=np.ones(cycles),
        windows=table,
        urdf=urdf,
    )
