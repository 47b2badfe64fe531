"""fatigue_pin: predictive simulation of motion with actuator fatigue.

A rigid-body model from a fixed-base URDF (Pinocchio), a fatigue model on every signed torque
actuator half (Xia 3CC, 3CC-S, 3CC-r, Michaud), a task with named cost terms, transcribed by
multiple shooting and solved with IPOPT over the whole task, window by window, or searched for
the maximum number of repetitions.

The names a study script needs are importable from here (``from fatigue_pin import Study,
run_study``); each lives in exactly one module of the subpackages, listed in docs/api.md and
docs/architecture.md. They are loaded on first use, so ``import fatigue_pin`` stays cheap.
"""

from __future__ import annotations

import importlib
from typing import Any

from fatigue_pin.core.version import __version__

# public name -> the module that owns it
_API: dict[str, str] = {
    # errors
    "FatiguePinError": "fatigue_pin.core.errors",
    "ModelError": "fatigue_pin.core.errors",
    "ParameterError": "fatigue_pin.core.errors",
    "DimensionError": "fatigue_pin.core.errors",
    "TaskError": "fatigue_pin.core.errors",
    # robot
    "RobotModel": "fatigue_pin.robot.model",
    "Payload": "fatigue_pin.robot.model",
    "ModelSource": "fatigue_pin.robot.model",
    "load_model": "fatigue_pin.robot.model",
    "read_osim": "fatigue_pin.robot.osim",
    "OsimModel": "fatigue_pin.robot.osim",
    "resolve_model": "fatigue_pin.robot.model",
    # fatigue
    "FatigueModel": "fatigue_pin.fatigue.interface",
    "XiaFatigue": "fatigue_pin.fatigue.models",
    "MichaudFatigue": "fatigue_pin.fatigue.michaud",
    "fatigue_model": "fatigue_pin.fatigue.models",
    "simulate": "fatigue_pin.fatigue.simulation",
    "FatigueTrajectory": "fatigue_pin.fatigue.simulation",
    "preset": "fatigue_pin.fatigue.presets",
    "PRESETS": "fatigue_pin.fatigue.presets",
    "load_preset_json": "fatigue_pin.fatigue.presets",
    "endurance_time": "fatigue_pin.fatigue.endurance",
    "endurance_table": "fatigue_pin.fatigue.endurance",
    "compare_frey_law_avin": "fatigue_pin.fatigue.endurance",
    "power_model_et": "fatigue_pin.fatigue.endurance",
    "sustained_et_closed_form": "fatigue_pin.fatigue.endurance",
    "FREY_LAW_AVIN_2010": "fatigue_pin.fatigue.endurance",
    "EnduranceData": "fatigue_pin.fatigue.calibration",
    "calibrate": "fatigue_pin.fatigue.calibration",
    "read_endurance_csv": "fatigue_pin.fatigue.calibration",
    # muscles
    "Muscle": "fatigue_pin.muscles.muscle",
    "PathPoint": "fatigue_pin.muscles.muscle",
    "CylinderWrap": "fatigue_pin.muscles.wraps",
    "WrapUse": "fatigue_pin.muscles.wraps",
    "MuscleSet": "fatigue_pin.muscles.muscle_set",
    "MuscleGeometry": "fatigue_pin.muscles.geometry",
    "FixedMomentArms": "fatigue_pin.muscles.geometry",
    "load_muscles": "fatigue_pin.muscles.files",
    # motors
    "ThermalNetwork": "fatigue_pin.motors.thermal",
    "MotorParameters": "fatigue_pin.motors.motor",
    "motor_preset": "fatigue_pin.motors.presets",
    "MotorThermal": "fatigue_pin.motors.thermal_states",
    "calibrate_thermal": "fatigue_pin.motors.calibration",
    # optimal control problem
    "SignedTorqueActuators": "fatigue_pin.ocp.actuators",
    "ActuationLayer": "fatigue_pin.ocp.actuation_layer",
    "MuscleActuators": "fatigue_pin.ocp.muscle_actuators",
    "MotorActuators": "fatigue_pin.ocp.motor_actuators",
    "Actuation": "fatigue_pin.ocp.actuation",
    "Task": "fatigue_pin.ocp.task",
    "JointTarget": "fatigue_pin.ocp.task_items",
    "StateTarget": "fatigue_pin.ocp.task_items",
    "JointRange": "fatigue_pin.ocp.task_items",
    "StateConstraint": "fatigue_pin.ocp.task_items",
    "FrameTarget": "fatigue_pin.ocp.task_items",
    "FrameOrientation": "fatigue_pin.ocp.task_items",
    "FramePlane": "fatigue_pin.ocp.task_items",
    "CostTerm": "fatigue_pin.ocp.costs",
    "cost_term": "fatigue_pin.ocp.costs",
    "Problem": "fatigue_pin.ocp.problem",
    "StateLayout": "fatigue_pin.ocp.problem",
    "Transcription": "fatigue_pin.ocp.transcription",
    "Ocp": "fatigue_pin.ocp.transcription",
    "SolverOptions": "fatigue_pin.ocp.solver",
    # drivers
    "OcpBuilder": "fatigue_pin.drivers.full",
    "solve_full": "fatigue_pin.drivers.full",
    "max_repetitions": "fatigue_pin.drivers.search",
    "SearchResult": "fatigue_pin.drivers.search",
    "solution_to_run": "fatigue_pin.drivers.run",
    "SlidingSettings": "fatigue_pin.drivers.sliding",
    "SlidingHorizon": "fatigue_pin.drivers.sliding",
    "Horizon": "fatigue_pin.drivers.horizon",
    "RunResult": "fatigue_pin.drivers.run",
    # closed loop (docs/mpc.md)
    "ClosedLoop": "fatigue_pin.drivers.mpc",
    "MpcSettings": "fatigue_pin.drivers.mpc",
    "Plant": "fatigue_pin.drivers.plant",
    "PlantSettings": "fatigue_pin.drivers.plant",
    "PlantNoise": "fatigue_pin.drivers.plant",
    "PlantDisturbance": "fatigue_pin.drivers.plant",
    "MheSettings": "fatigue_pin.drivers.estimation",
    "run_closed_loop": "fatigue_pin.drivers.mpc_run",
    "MpcStudy": "fatigue_pin.io.mpc_study",
    "run_mpc": "fatigue_pin.io.mpc_study",
    # files
    "Study": "fatigue_pin.io.study",
    "StudyError": "fatigue_pin.core.errors",
    "run_study": "fatigue_pin.io.study",
    "StudyResult": "fatigue_pin.io.study",
    "ResultFileError": "fatigue_pin.core.errors",
    "ResultFile": "fatigue_pin.io.results",
    "read_run": "fatigue_pin.io.results",
    "write_run": "fatigue_pin.io.results",
    "list_runs": "fatigue_pin.io.results",
    # checks, sweeps, views
    "verify_run": "fatigue_pin.verify.verifier",
    "VerifyTolerances": "fatigue_pin.verify.report",
    "VerifyReport": "fatigue_pin.verify.report",
    "Sweep": "fatigue_pin.sweep.plan",
    "run_sweep": "fatigue_pin.sweep.runner",
    "local_cluster": "fatigue_pin.sweep.cluster",
    "read_summary": "fatigue_pin.sweep.summary",
    "plot_run": "fatigue_pin.viz.plots",
    "plot_file": "fatigue_pin.viz.plots",
    "export_html": "fatigue_pin.viz.replay",
    "plot_sweep": "fatigue_pin.viz.sweeps",
    # the paper's study
    "curl_study": "fatigue_pin.paper.curl",
}

__all__ = sorted(_API) + ["__version__"]


def __getattr__(name: str) -> Any:
    """Load a public name from its module on first use (PEP 562)."""
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'fatigue_pin' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))
