"""Exceptions raised by fatigue_pin. Every message names the bad value and what was expected."""


class FatiguePinError(Exception):
    """Base class of all fatigue_pin errors. A message is one line: line breaks that reach it
    from the input (a key or a value holding a newline) are written ``\\n``."""

    def __init__(self, *args: object) -> None:
        if args and isinstance(args[0], str):
            args = (args[0].replace("\r", "\\r").replace("\n", "\\n"),) + args[1:]
        super().__init__(*args)


class ModelError(FatiguePinError, ValueError):
    """A URDF or model that fatigue_pin cannot use (missing file, parse error, floating base, ...)."""


class ParameterError(FatiguePinError, ValueError):
    """A parameter set with a bad field (negative rate, non-finite value, unstable stabiliser, ...)."""


class DimensionError(FatiguePinError, ValueError):
    """A state, control or parameter vector of the wrong size."""


class TaskError(FatiguePinError, ValueError):
    """A task that cannot be posed on the model (unknown joint, target outside the joint range, ...)."""


class ResultFileError(FatiguePinError, ValueError):
    """A result file or run that cannot be read or written (missing, damaged, foreign, newer
    layout, no room, ...)."""


class OutputLocationError(ResultFileError):
    """An output path that cannot receive files (a file where a folder is expected, a folder that
    cannot be created or written to, a full disk, a wrong file name)."""


class StudyError(FatiguePinError, ValueError):
    """A study file or table that cannot be used (unknown key, wrong type, missing key, ...)."""


class PresetFileError(ParameterError):
    """A parameter file (JSON) that cannot be used as a preset."""


class SweepError(FatiguePinError, ValueError):
    """A sweep file that cannot be used, or a sweep output folder that cannot receive results."""


class CalibrationDataError(ParameterError):
    """Endurance data that cannot be fitted (missing column, bad value, too few rows, ...)."""


class UsageError(FatiguePinError, ValueError):
    """A command line that does not parse (unknown command or option, bad value)."""


class CompileError(FatiguePinError, RuntimeError):
    """Generated code could not be compiled (compiler missing or failing)."""
