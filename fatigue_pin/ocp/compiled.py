"""Compiled CasADi functions, cached on disk: one library per model, used by every horizon.

Compiling the complete NLP of a horizon (objective, constraints, gradient, Jacobian and exact
Hessian of the Lagrangian) costs about a minute for arm26, and the generated C differs with every
horizon length, so every new horizon paid that minute again. Nearly all of that C is the
per-interval functions (RK4 of Pinocchio's ABA, RK4 of the fatigue model) and their derivatives,
which do not depend on the horizon. This module compiles them once:

1. :meth:`FunctionLibrary.build` generates C for a set of functions *and the derivative
   functions CasADi asks for when they are called inside an NLP*: for every function ``f`` also
   ``jac_f`` (its Jacobian), ``adj1_f`` (one reverse sweep, for gradients) and ``jac_adj1_f``
   (the Jacobian of the reverse sweep, for the exact Hessian). It compiles them into one shared
   library, cached under :func:`library_key` (which does not contain the horizon).
   :meth:`FunctionLibrary.function` loads one of them with ``casadi.external``. CasADi finds the
   derivative functions by these names, so forward and reverse derivatives of any order up to
   two, in any number of directions, come from compiled code (forward directions are products of
   the compiled Jacobian with the seeds). The externals can be ``map``-ped and called inside MX
   expressions like the original functions.
2. The NLP of any horizon is assembled around those externals by CasADi's virtual machine
   (:mod:`fatigue_pin.ocp.transcription`, library mode). Its constraint Jacobian and Lagrangian
   Hessian come from per-interval derivative blocks (:mod:`fatigue_pin.ocp.blocks`), compiled in
   the same library as ``plain`` functions (no derivative functions of their own), so the
   library then needs of the interval functions only their gradients. A small compiled driver per horizon, linked
   against the library, was measured and dropped: its C grows with the horizon (22 s of compile
   at 1 cycle, 132 s at 32).

Cache entries (``<cache>/<name>_<key>.so``) are written atomically (compiled in a temporary
directory beside the cache entry, then ``os.replace``), builders of the same key serialise on
an ``fcntl.flock`` of ``<entry>.lock``, and every entry carries ``<entry>.sha256``: a library
whose checksum is missing or wrong (a truncated copy, a crash between the two writes, a
corrupted disk) is rebuilt, never loaded.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import platform
import re
import shutil
import subprocess
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator, Mapping, Sequence

import casadi as ca

from fatigue_pin.core.cores import usable_cores
from fatigue_pin.core.errors import CompileError, ParameterError
from fatigue_pin.core.files import atomic_write_bytes, locked
from fatigue_pin.core.text import shown

#: Version of the library layout produced here; part of every cache key.
FORMAT_VERSION = "3"
#: Derivative functions compiled beside every library function, always: one forward direction,
#: one reverse sweep and one forward direction over it. CasADi builds every derivative it needs
#: from these when the library has no better one (``fwdK_f`` from K calls of ``fwd1_f``), so
#: first and second derivatives are exact and compiled whatever is asked; the prefixes from
#: :func:`requested_derivatives` add the faster exact set (``fwd10_f`` in one call). Without a
#: usable derivative CasADi raises "Derivatives cannot be calculated"; it never falls back to
#: finite differences.
DEFAULT_DERIVATIVES = ("fwd1_", "adj1_", "fwd1_adj1_")
#: The functions of an ``nlpsol`` that a driver holds (what ``generate_dependencies`` writes).
NLP_FUNCTIONS = ("nlp_f", "nlp_g", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l", "nlp_grad")
#: Rough compile speed used for the progress message (bytes of generated C per second and core
#: at -O3 -march=native). Set from measured builds on 2 cores: arm26's library in about 5 s, the
#: Panda's (9 DoF) in about 81 s; the earlier 25 000 announced 26 s and 380 s for them.
_COMPILE_BYTES_PER_S = 120_000.0
#: The same for one large file (gcc slows down on long functions): the pendulum's 1.06 MB Hessian
#: block of its rigid body took 16 s at -O3 -march=native, where the rate above gives 9 s.
_LARGE_FILE_BYTES_PER_S = 65_000.0
_DERIVATIVE = re.compile(r"(fwd[1-9][0-9]*_|adj[1-9][0-9]*_|jac_)")

Progress = Callable[[str], None]


def cache_folder(cache_dir: str | Path | None = None) -> Path:
    """The compiled-code cache folder, absolute: ``cache_dir`` if given, else
    ``$FATIGUE_PIN_CACHE``, else ``~/.cache/fatigue_pin``. The one place that resolves it."""
    if cache_dir is not None:
        return Path(cache_dir).absolute()
    env = os.environ.get("FATIGUE_PIN_CACHE")
    return (Path(env) if env else Path.home() / ".cache" / "fatigue_pin").absolute()


@dataclass(frozen=True)
class BuildOptions:
    """How generated C is compiled and where the results are cached.

    Attributes:
        compiler: C compiler command (looked up on ``PATH`` only when something is compiled).
        flags: optimisation flags. With ``-march=native`` (or any ``=native`` flag) the cache key
            includes the CPU, and if the compiler rejects the flag the portable rest is used.
        cache_dir: cache directory (default ``$FATIGUE_PIN_CACHE`` or ``~/.cache/fatigue_pin``).
        openmp: compile with ``-fopenmp`` when the code carries OpenMP pragmas (maps with
            ``parallel="openmp"``); without OpenMP support the pragmas are ignored (serial).
        jobs: compiler processes run at once for a library (one C file per function); ``None``
            for every core. Not part of the cache key.
    """

    compiler: str = "gcc"
    flags: tuple[str, ...] = ("-O3", "-march=native")
    cache_dir: Path | None = None
    openmp: bool = True
    jobs: int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.compiler, str) or not self.compiler.strip():
            raise ParameterError(f"BuildOptions.compiler = {self.compiler!r}: expected a compiler command such as 'gcc'")
        if isinstance(self.flags, str) or not all(isinstance(f, str) for f in self.flags):
            raise ParameterError(f"BuildOptions.flags = {self.flags!r}: expected a tuple of strings such as ('-O3',)")
        object.__setattr__(self, "flags", tuple(self.flags))
        if self.jobs is not None and (int(self.jobs) != self.jobs or self.jobs < 1):
            raise ParameterError(f"BuildOptions.jobs = {shown(self.jobs)}: expected an integer >= 1 or None (every core)")

    def resolved_jobs(self) -> int:
        """Compiler processes run at once."""
        return int(self.jobs) if self.jobs is not None else usable_cores()

    def resolved_cache_dir(self) -> Path:
        """Directory of the compiled-code cache (:func:`cache_folder`)."""
        return cache_folder(self.cache_dir)


# -- cache keys ------------------------------------------------------------------------------------


def is_native_flag(flag: str) -> bool:
    """Whether a compiler flag tunes the code to this CPU (``-march=native``, ``-mtune=native``)."""
    return flag.endswith("=native")


def host_key(flags: Sequence[str]) -> bytes:
    """What a cache key adds for code tuned to this CPU: its model and instruction-set flags
    (empty without a ``=native`` flag), so a cache shared between machines (a network home
    directory) never hands one machine's library to another."""
    if not any(is_native_flag(flag) for flag in flags):
        return b""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
        picked = [line for line in lines if line.startswith(("model name", "flags", "Features", "CPU part"))]
        return "\n".join(sorted(set(picked))).encode()
    except OSError:
        return (platform.machine() + platform.processor()).encode()


def _named(functions: Mapping[str, ca.Function] | Sequence[ca.Function]) -> dict[str, ca.Function]:
    """``functions`` as name -> Function, sorted by name; a mapping's keys must be the names."""
    if isinstance(functions, Mapping):
        for key, f in functions.items():
            if not isinstance(f, ca.Function):
                raise ParameterError(f"functions[{key!r}] is a {type(f).__name__}: expected a casadi.Function")
            if f.name() != key:
                raise ParameterError(f"functions[{key!r}] is named {f.name()!r}: the key must be the function's name")
        named = dict(functions)
    else:
        named = {}
        for f in functions:
            if not isinstance(f, ca.Function):
                raise ParameterError(f"functions holds a {type(f).__name__}: expected casadi.Function objects")
            if f.name() in named:
                raise ParameterError(f"two functions are named {f.name()!r}: names must be unique")
            named[f.name()] = f
    if not named:
        raise ParameterError("functions is empty: expected at least one casadi.Function")
    return dict(sorted(named.items()))


Derivatives = Mapping[str, Sequence[str]]


def _derivative_spec(named: Mapping[str, ca.Function], derivatives: Sequence[str] | Derivatives | None) -> dict[str, tuple[str, ...]]:
    """Derivative prefixes of every function: ``derivatives`` is one sequence of prefixes for
    all functions (e.g. ``("fwd8_", "fwd6_adj1_")``) or a mapping name -> prefixes, always with
    :data:`DEFAULT_DERIVATIVES` added. Sorted, without duplicates."""
    if derivatives is None:
        derivatives = ()
    if isinstance(derivatives, str):
        raise ParameterError(f"derivatives = {derivatives!r}: expected a sequence of prefixes such as ('fwd1_', 'adj1_'), not a string")
    if isinstance(derivatives, Mapping):
        unknown = sorted(set(derivatives) - set(named))
        if unknown:
            raise ParameterError(f"derivatives names functions {unknown} that are not in the library {sorted(named)}")
        spec = {name: tuple(derivatives.get(name, DEFAULT_DERIVATIVES)) for name in named}
    else:
        spec = {name: tuple(derivatives) for name in named}
    for name, prefixes in spec.items():
        for prefix in prefixes:
            if not isinstance(prefix, str) or not re.fullmatch(f"{_DERIVATIVE.pattern}+", prefix):
                raise ParameterError(
                    f"derivative prefix {prefix!r} of {name!r}: expected CasADi derivative prefixes such as "
                    f"'fwd8_', 'adj1_', 'jac_', 'fwd6_adj1_', 'jac_adj1_'"
                )
        spec[name] = tuple(sorted(set(prefixes) | set(DEFAULT_DERIVATIVES)))
    return spec


def derivative(f: ca.Function, prefix: str) -> ca.Function:
    """The derivative function of ``f`` named ``prefix + f.name()`` (CasADi's naming), e.g.
    ``fwd8_`` (8 forward directions), ``adj1_`` (one reverse sweep), ``jac_`` (all Jacobian
    blocks), ``fwd6_adj1_`` (6 forward directions of the reverse sweep: Hessian-vector products).
    The prefixes are applied right to left."""
    parts = _DERIVATIVE.findall(prefix)
    if "".join(parts) != prefix:
        raise ParameterError(f"derivative prefix {prefix!r}: expected a chain of 'fwdK_', 'adjK_' and 'jac_'")
    base = f.name()
    for part in reversed(parts):
        if part == "jac_":
            f = f.jacobian()
        elif part.startswith("fwd"):
            f = f.forward(int(part[3:-1]))
        else:
            f = f.reverse(int(part[3:-1]))
    if f.name() != prefix + base:
        raise ParameterError(f"derivative {prefix!r} of {base!r} came out named {f.name()!r}; CasADi would not find it by name")
    return f


def library_key(
    functions: Mapping[str, ca.Function] | Sequence[ca.Function],
    options: BuildOptions,
    derivatives: Sequence[str] | Derivatives | None = None,
    plain: Mapping[str, ca.Function] | Sequence[ca.Function] = (),
) -> str:
    """Cache key of a library (20 hex digits).

    Inputs, and only these: every function's name and serialised graph (so the model, the
    fatigue model, the integrator, the interval length and any constant baked in), the
    derivative functions compiled beside each, the ``plain`` functions (compiled without
    derivatives, e.g. the derivative blocks of :mod:`fatigue_pin.ocp.blocks`), the compiler command and flags, whether OpenMP
    is used, the CasADi version (it generates the C), the CPU when a flag is ``=native``
    (:func:`host_key`) and :data:`FORMAT_VERSION`. The horizon is not an input: it only appears
    in the NLP assembled around the library.
    """
    named = _named(functions)
    spec = _derivative_spec(named, derivatives)
    h = hashlib.sha256()
    for part in (
        f"fatigue_pin.compiled/{FORMAT_VERSION}",
        f"casadi/{ca.__version__}",
        f"compiler/{options.compiler}",
        "flags/" + " ".join(options.flags),
        f"openmp/{options.openmp}",
    ):
        h.update(part.encode() + b"\0")
    h.update(host_key(options.flags) + b"\0")
    for name, f in named.items():
        h.update(name.encode() + b"\0" + " ".join(spec[name]).encode() + b"\0" + f.serialize().encode() + b"\0")
    for name, f in (_named(plain) if plain else {}).items():
        h.update(b"plain\0" + name.encode() + b"\0" + f.serialize().encode() + b"\0")
    return h.hexdigest()[:20]


# -- cache entries: checksum, lock, atomic write ---------------------------------------------------


def lock_path(entry: Path) -> Path:
    """The build lock of cache entry ``entry`` (``<entry>.lock``): held while it is compiled."""
    return entry.with_name(entry.name + ".lock")


def _checksum_path(entry: Path) -> Path:
    return entry.with_name(entry.name + ".sha256")


def _file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def verify_entry(entry: Path) -> bool:
    """Whether ``entry`` exists and matches the checksum stored beside it."""
    checksum = _checksum_path(entry)
    try:
        expected = checksum.read_text().strip()
        return bool(expected) and _file_sha256(entry) == expected
    except OSError:
        return False


def cached_build(entry: Path, build: Callable[[Path], None]) -> bool:
    """Make ``entry`` a valid cache entry; return whether it had to be built.

    ``build(tmp_path)`` must write the file at ``tmp_path`` (a path in a temporary directory
    beside ``entry``). Under the entry's lock: if the entry verifies (another process may just
    have built it) nothing is done; otherwise the old entry and checksum are removed, ``build``
    runs, the result is renamed into place and its checksum is written last, so a crash at any
    point leaves either no entry or one that fails verification.
    """
    if verify_entry(entry):
        return False
    with locked(lock_path(entry)):
        if verify_entry(entry):
            return False
        for stale in (_checksum_path(entry), entry):
            with contextlib.suppress(FileNotFoundError):
                stale.unlink()
        with tempfile.TemporaryDirectory(dir=entry.parent, prefix=entry.name + ".build.") as tmp:
            tmp_path = Path(tmp) / entry.name
            build(tmp_path)
            digest = _file_sha256(tmp_path)
            os.replace(tmp_path, entry)
        atomic_write_bytes(_checksum_path(entry), (digest + "\n").encode())
    return True


# -- compiling ---------------------------------------------------------------------------------------


def _compiler_path(compiler: str) -> str:
    path = shutil.which(compiler)
    if path is None:
        raise CompileError(
            f"C compiler {compiler!r} is not on PATH (needed to compile CasADi-generated code); install it, "
            f"name another one in the compiler option, or turn compilation off"
        )
    return path


def _flag_attempts(options: BuildOptions, openmp: bool) -> list[list[str]]:
    """Flag sets to try, most capable first: OpenMP and CPU tuning, then without each."""
    portable = tuple(f for f in options.flags if not is_native_flag(f))
    attempts: list[list[str]] = []
    for flags in dict.fromkeys((options.flags, portable)):
        if openmp:
            attempts.append(["-fopenmp", *flags])
        attempts.append(list(flags))
    return attempts


def _run_first(commands: Sequence[list[str]], what: str) -> list[str]:
    """Run the commands in turn until one succeeds; return it (CompileError if none does)."""
    proc = None
    for cmd in commands:
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode == 0:
            return cmd
    assert proc is not None
    raise CompileError(f"compiling {what} failed ({' '.join(commands[-1])}):\n{proc.stderr[-4000:]}")


def compile_shared(sources: Sequence[Path], target: Path, options: BuildOptions) -> list[str]:
    """Compile C ``sources`` into the shared library ``target``; return the flags that worked.

    One source is compiled and linked in one step; several are compiled to objects by
    ``options.resolved_jobs()`` compiler processes at once, then linked. ``-fopenmp`` is added
    when the code has OpenMP pragmas (and ``options.openmp``); if that or a ``=native`` flag is
    rejected, the compile is retried without it.
    """
    compiler = _compiler_path(options.compiler)
    openmp = options.openmp and any(b"#pragma omp" in src.read_bytes() for src in sources)
    attempts = _flag_attempts(options, openmp)
    if len(sources) == 1:
        cmds = [[compiler, "-fPIC", "-shared", *flags, str(sources[0]), "-o", str(target), "-lm"] for flags in attempts]
        return _run_first(cmds, sources[0].name)
    # find the flags that work on the smallest source, then compile all with them in parallel
    smallest = min(sources, key=lambda src: src.stat().st_size)
    probe = [[compiler, "-fPIC", "-c", *flags, str(smallest), "-o", str(smallest.with_suffix(".o"))] for flags in attempts]
    flags = _run_first(probe, smallest.name)[3:-3]
    rest = [src for src in sources if src != smallest]
    with ThreadPoolExecutor(max_workers=options.resolved_jobs()) as pool:
        list(pool.map(lambda src: _run_first([[compiler, "-fPIC", "-c", *flags, str(src), "-o", str(src.with_suffix(".o"))]], src.name),
                      sorted(rest, key=lambda src: -src.stat().st_size)))
    objects = [str(src.with_suffix(".o")) for src in sources]
    _run_first([[compiler, "-shared", *flags, *objects, "-o", str(target), "-lm"]], target.name)
    return flags


def expected_compile_s(sizes: Sequence[int], jobs: int) -> float:
    """About how long compiling C files of these ``sizes`` (bytes) takes with ``jobs`` compiler
    processes (s): the total at :data:`_COMPILE_BYTES_PER_S` per process, or the largest file
    alone at :data:`_LARGE_FILE_BYTES_PER_S` when it takes longer (one process compiles it)."""
    if not sizes:
        return 0.0
    return max(sum(sizes) / _COMPILE_BYTES_PER_S / max(1, min(jobs, len(sizes))), max(sizes) / _LARGE_FILE_BYTES_PER_S)


@contextlib.contextmanager
def _announce(progress: Progress | None, what: str, sources: Sequence[Path], options: BuildOptions, once: str) -> Iterator[None]:
    """Say what is compiled and about how long it takes; with a
    :class:`~fatigue_pin.core.progress.Reporter`, a live line (or heartbeat lines) while it runs."""
    seconds = max(1.0, expected_compile_s([src.stat().st_size for src in sources], options.resolved_jobs()))
    seconds = round(seconds, -1) if seconds > 30 else round(seconds)
    text = f"compiling {what} ({once})"
    task = getattr(progress, "task", None)
    if task is not None:
        with task(text, expected_s=seconds):
            yield
        return
    if progress is not None:
        progress(f"compiling {what} (about {seconds:.0f} s, {once})")
    yield


# -- the per-model library ---------------------------------------------------------------------------


def derivative_functions(f: ca.Function, prefixes: Sequence[str] = DEFAULT_DERIVATIVES) -> list[ca.Function]:
    """``f`` and its derivative functions named ``prefix + f.name()`` (see :func:`derivative`)."""
    return [f] + [derivative(f, prefix) for prefix in prefixes]


def requested_derivatives(solver: ca.Function, names: Sequence[str]) -> dict[str, tuple[str, ...]]:
    """The derivative functions of ``names`` that an NLP evaluates, as prefixes per name.

    ``solver`` is an ``nlpsol`` (not solved, not compiled) of the problem formulated with the
    *original* functions; every function embedded in its NLP functions (:data:`NLP_FUNCTIONS`)
    is visited, and those named ``<prefixes><name>`` are collected, e.g. ``{"F_rb": ("adj1_",
    "fwd10_", "fwd6_adj1_")}``. CasADi picks the number of forward directions from the colouring
    of the NLP's Jacobian and Hessian, which depends on the problem's structure, not on its
    horizon. Compiling exactly these makes the library's derivatives the ones a fully generated
    NLP would have used.
    """
    seen: dict[str, ca.Function] = {}
    stack = [solver.get_function(fname) for fname in NLP_FUNCTIONS if solver.has_function(fname)]
    while stack:
        for g in stack.pop().find_functions():
            if g.name() not in seen:
                seen[g.name()] = g
                stack.append(g)
    pattern = re.compile(f"(?P<prefix>(?:{_DERIVATIVE.pattern})+)(?P<name>" + "|".join(map(re.escape, names)) + ")")
    found: dict[str, set[str]] = {name: set() for name in names}
    for fname in seen:
        m = pattern.fullmatch(fname)
        if m:
            found[m.group("name")].add(m.group("prefix"))
    return {name: tuple(sorted(prefixes)) for name, prefixes in found.items()}


@dataclass(frozen=True)
class FunctionLibrary:
    """A compiled, cached shared library of CasADi functions and their derivatives.

    Attributes:
        name: library name (a C identifier; the cache entry is ``<name>_<key>.so``).
        key: :func:`library_key` of the functions, derivatives and options.
        path: the verified shared library.
        names: names of the functions given to :meth:`build` (``functions``, then ``plain``).
        derivatives: per function, the derivative prefixes compiled beside it (CasADi finds
            ``<prefix><name>`` in the library when it differentiates the external); none for
            the plain functions.
        compile_time_s: time spent generating and compiling (0 when found in the cache).
    """

    name: str
    key: str
    path: Path
    names: tuple[str, ...]
    derivatives: Mapping[str, tuple[str, ...]]
    compile_time_s: float = 0.0
    _loaded: dict[str, ca.Function] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def build(
        cls,
        functions: Mapping[str, ca.Function] | Sequence[ca.Function],
        name: str,
        options: BuildOptions | None = None,
        derivatives: Sequence[str] | Derivatives | None = None,
        progress: Progress | None = None,
        description: str | None = None,
        plain: Mapping[str, ca.Function] | Sequence[ca.Function] = (),
        background: bool = False,
    ) -> FunctionLibrary | None:
        """Find the library of ``functions`` in the cache, or generate, compile and cache it.

        Args:
            functions: the functions (any CasADi Function that supports code generation: SX,
                MX with calls of SX functions, maps, ...), as a list or as name -> Function.
            name: library name, e.g. ``"arm26_intervals"`` (letters, digits, underscores).
            options: compiler, flags, cache directory, parallel jobs.
            derivatives: derivative prefixes compiled beside every function besides
                :data:`DEFAULT_DERIVATIVES` (one sequence for all, or name -> sequence). Pass the
                result of :func:`requested_derivatives` for the fastest exact set.
            progress: called with one line, e.g. "compiling the arm26 interval functions (about
                60 s, once per machine)", before a compile (not when the cache has it).
            description: what the progress line calls the functions (default: ``name``).
            plain: functions compiled as they are, without derivative functions (their names
                must differ from those of ``functions``).
            background: on a cache miss, write the C and compile it in a detached process
                (:mod:`fatigue_pin.ocp.background`) and return None at once: the caller goes on
                with the uncompiled functions, and a later build finds the library cached.
        """
        options = options or BuildOptions()
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
            raise ParameterError(f"library name {name!r}: expected a C identifier (letters, digits, underscores)")
        named = _named(functions)
        spec = _derivative_spec(named, derivatives)
        extra = _named(plain) if plain else {}
        if set(extra) & set(named):
            raise ParameterError(f"functions {sorted(set(extra) & set(named))} are given both with and without derivatives")
        key = library_key(named, options, spec, extra)
        entry = options.resolved_cache_dir() / f"{name}_{key}.so"
        t0 = time.perf_counter()

        def write_sources(folder: Path) -> list[Path]:
            sources = []
            compiled_names = {prefix + fname for fname in named for prefix in ("", *spec[fname])} | set(extra)
            units = [g for fname, f in named.items() for g in derivative_functions(f, spec[fname])] + list(extra.values())
            for g in units:  # one C file per function and derivative: parallel compile
                generator = ca.CodeGenerator(f"{name}_{g.name()}", {"verbose": False})
                # with its Jacobian sparsity (symbols jac_<g>_sparsity_*), so that the NLP keeps
                # its exact pattern, unless jac_<g> itself is compiled (it gives the pattern)
                generator.add(g, "jac_" + g.name() not in compiled_names)
                sources.append(Path(generator.generate(str(folder) + os.sep)))
            return sources

        def build(tmp_so: Path) -> None:
            sources = write_sources(tmp_so.parent)
            with _announce(progress, description or name, sources, options, "once per machine"):
                compile_shared(sources, tmp_so, options)

        if background and not verify_entry(entry):
            from fatigue_pin.ocp.background import start

            started = start(entry, write_sources, options)
            if progress is not None:
                what = description or name
                progress(f"compiling {what} in the background (once per machine); this run is solved without compiled code"
                         if started else f"{what} are being compiled by another process; this run is solved without compiled code")
            return None
        built = cached_build(entry, build)
        spec.update({fname: () for fname in extra})
        return cls(name, key, entry, tuple(named) + tuple(extra), spec, time.perf_counter() - t0 if built else 0.0)

    def function(self, name: str) -> ca.Function:
        """The compiled function ``name`` as a ``casadi.external`` (loaded once per library object).

        It has the original's inputs, outputs and sparsity; calls, maps and derivatives run
        compiled code (CasADi composes any derivative it needs from the compiled ones).
        """
        if name not in self.names:
            raise ParameterError(f"function {name!r} is not in library {self.name!r}; it has {list(self.names)}")
        if name not in self._loaded:
            if not verify_entry(self.path):
                raise CompileError(f"library {self.path} is missing or fails its checksum; build it again")
            self._loaded[name] = ca.external(name, str(self.path))
        return self._loaded[name]

    def functions(self) -> dict[str, ca.Function]:
        """Every function of the library (name -> external)."""
        return {name: self.function(name) for name in self.names}
