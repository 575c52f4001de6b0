"""OpenCL devices, contexts and programs.

Device choice (docs/design.md, "OpenCL conventions"): an explicit ``device`` argument (``--device``
on the command line), else ``PYOPENCL_CTX``, else the first GPU that can build kernels, else
the first such CPU (PoCL). A device "can build" when a tiny test kernel compiles on it: PyPI's
``pocl-binary-distribution`` 3.0 lists the CPU but fails every build here ("unknown target
CPU 'generic'"), so listing a device is not enough.

Kernel sources live in the package ``clsonar.kernels`` (the source tree's ``kernels/``) and
are read with :mod:`importlib.resources`, so an installed wheel finds them. ``#include "x.h"``
lines are expanded from the same package before the build; compile options (``-D``) carry
the constants. Programs are built once per (context, source, options) and reused, and
kept built on disk (:data:`PROGRAM_CACHE`), so a new process loads them instead of
building them again.
"""

from __future__ import annotations

import hashlib
import os
import re
import sys
import types
import warnings
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path

import numpy as np

from .errors import DeviceError
from .files import write_atomic
from .numerics import installed_version

KERNEL_PACKAGE = "clsonar.kernels"

#: What to tell a user whose machine has no OpenCL device that can build kernels.
INSTALL_HINT = (
    "install an OpenCL runtime that can build kernels, e.g. on Debian/Ubuntu: "
    "sudo apt-get install -y pocl-opencl-icd (PoCL 3.1; PyPI's pocl-binary-distribution 3.0 "
    "cannot build kernels on many CPUs); for a GPU, its vendor's OpenCL driver"
)

_PROBE_SOURCE = "__kernel void probe(__global float *a) { a[get_global_id(0)] *= 2.0f; }"


def _cl():
    """Import pyopencl lazily, so ``import clsonar`` works (and says why) without it."""
    first = "pyopencl" not in sys.modules
    if first:
        _versions_from_folders()
    try:
        import pyopencl as cl
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise DeviceError(f"pyopencl cannot be imported ({e}); pip install pyopencl") from None
    if first:
        for package in VERSIONED:  # the attribute an import of the real module would set
            if not hasattr(sys.modules.get(package), "version") \
                    and f"{package}.version" in sys.modules:
                vars(sys.modules[package])["version"] = sys.modules[f"{package}.version"]
    return cl


#: The packages under pyopencl whose ``version`` module asks :mod:`importlib.metadata`.
VERSIONED = ("pytools", "pyopencl")
_RELEASE = re.compile(r"^([0-9.]+)([a-z0-9]*?)$")  # their modules' own pattern


def _versions_from_folders() -> None:
    """``pytools.version`` and ``pyopencl.version`` made before pyopencl imports them, with
    the same three names (``VERSION_TEXT``, ``VERSION_STATUS``, ``VERSION``) from each
    wheel's ``dist-info`` folder name (:func:`~clsonar.numerics.installed_version`). Their
    own modules call ``importlib.metadata.version``, whose import (with ``email``,
    ``socket``, ``zipfile`` and ``csv``) and search of every installed distribution cost
    20–30 ms of a 0.5 s run; tests/test_speed_startup.py holds the names to theirs. A
    version of another form is left to the package's own module."""
    for package in VERSIONED:
        name = f"{package}.version"
        if package in sys.modules or name in sys.modules:
            continue
        try:
            text = installed_version(package)
        except ImportError:  # not installed: its import says so
            continue
        match = _RELEASE.match(text)
        if match is None:
            continue
        module = types.ModuleType(name, f"{package}'s version, from its dist-info folder")
        vars(module).update(VERSION_TEXT=text, VERSION_STATUS=match.group(2),
                            VERSION=tuple(int(nr) for nr in match.group(1).split(".")))
        sys.modules[name] = module


@dataclass(frozen=True)
class DeviceInfo:
    """One OpenCL device as ``clsonar devices`` lists it."""

    index: str  # "platform:device", the form --device and PYOPENCL_CTX take
    platform: str
    name: str
    kind: str  # "GPU", "CPU" or "other"
    fp64: bool
    global_mem_bytes: int
    problem: str  # empty when the device builds kernels, else a one-line reason

    @property
    def usable(self) -> bool:
        return not self.problem


def _platforms():
    cl = _cl()
    try:
        return cl.get_platforms()
    except cl.Error:
        return []


def device_kind(device) -> str:
    """``"GPU"``, ``"CPU"`` or ``"other"``: how kernels should be launched on ``device``."""
    cl = _cl()
    if device.type & cl.device_type.GPU:
        return "GPU"
    if device.type & cl.device_type.CPU:
        return "CPU"
    return "other"


@cache
def _build_problem(device) -> str:
    """Empty string if a test kernel builds on ``device``, else a one-line reason."""
    cl = _cl()
    try:
        ctx = cl.Context([device])
        _built(ctx, _PROBE_SOURCE, ())
    except cl.Error as e:
        lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
        detail = next((ln for ln in lines if "error" in ln.lower() and "build" not in ln.lower()),
                      lines[0] if lines else type(e).__name__)
        return f"cannot build kernels ({detail[:160]})"
    return ""


def list_devices() -> list[DeviceInfo]:
    """Every OpenCL device visible, each with whether it can build kernels."""
    out = []
    for pi, platform in enumerate(_platforms()):
        try:
            devices = platform.get_devices()
        except _cl().Error:
            continue
        for di, d in enumerate(devices):
            out.append(DeviceInfo(
                index=f"{pi}:{di}",
                platform=platform.name.strip(),
                name=d.name.strip(),
                kind=device_kind(d),
                fp64="cl_khr_fp64" in d.extensions,
                global_mem_bytes=int(d.global_mem_size),
                problem=_build_problem(d),
            ))
    return out


def _device_by_index(spec: str):
    m = re.fullmatch(r"\s*(\d+)\s*(?::\s*(\d+)\s*)?", spec)
    if not m:
        return None
    platforms = _platforms()
    pi, di = int(m.group(1)), int(m.group(2) or 0)
    if pi >= len(platforms):
        raise DeviceError(f"device {spec!r}: there is no OpenCL platform {pi} "
                          f"({len(platforms)} found; see 'clsonar devices')")
    devices = platforms[pi].get_devices()
    if di >= len(devices):
        raise DeviceError(f"device {spec!r}: platform {pi} has no device {di} "
                          f"({len(devices)} found; see 'clsonar devices')")
    return devices[di]


def choose_device(spec: str | None = None):
    """The ``pyopencl.Device`` to use (see the module docstring for the order of choice).

    ``spec`` is ``"P:D"`` (platform and device index, as ``clsonar devices`` prints) or a
    case-insensitive part of the device or platform name, e.g. ``"cpu"``, ``"nvidia"``.
    Raises :class:`DeviceError` with the fix when nothing usable is found.
    """
    source = "--device"
    if spec is None and os.environ.get("PYOPENCL_CTX"):
        spec, source = os.environ["PYOPENCL_CTX"], "PYOPENCL_CTX"
    if spec is not None:
        device = _device_by_index(spec)
        if device is None:
            needle = spec.lower()
            matches = [d for p in _platforms() for d in p.get_devices()
                       if needle in d.name.lower() or needle in p.name.lower()
                       or needle == device_kind(d).lower()]
            if not matches:
                raise DeviceError(f"{source} {spec!r} matches no OpenCL device "
                                  "(see 'clsonar devices')")
            usable = [d for d in matches if not _build_problem(d)]
            device = (usable or matches)[0]
        problem = _build_problem(device)
        if problem:
            raise DeviceError(f"{source} {spec!r}: {device.name.strip()} {problem}; {INSTALL_HINT}")
        return device
    devices = [d for p in _platforms() for d in p.get_devices()]
    if not devices:
        raise DeviceError(f"no OpenCL platform or device found: {INSTALL_HINT}")
    for wanted in ("GPU", "CPU", "other"):
        for d in devices:
            if device_kind(d) == wanted and not _build_problem(d):
                return d
    names = ", ".join(d.name.strip() for d in devices)
    raise DeviceError(f"no OpenCL device here can build kernels ({names}): {INSTALL_HINT}")


@cache
def _context_for(device):
    return _cl().Context([device])


def get_context(device: str | None = None):
    """A ``pyopencl.Context`` on the chosen device (one per device, reused)."""
    return _context_for(choose_device(device))


@cache
def queue(context):
    """The command queue of ``context`` (one per context, reused)."""
    return _cl().CommandQueue(context)


#: The arithmetic a kernel can be built for: ``precision`` name → NumPy type of its reals.
PRECISIONS: dict[str, type[np.floating]] = {"float32": np.float32, "float64": np.float64}


def context_for(context=None, device: str | None = None, precision: str = "float32"):
    """``context``, or the one of ``device`` (:func:`get_context`), checked for
    ``precision``: ``ValueError`` for an unknown one, :class:`DeviceError` for float64 on
    a device without ``cl_khr_fp64``."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, not {precision!r}")
    ctx = context if context is not None else get_context(device)
    if precision == "float64" and not has_fp64(ctx):
        raise DeviceError(f"{ctx.devices[0].name.strip()} has no cl_khr_fp64: "
                          "use precision='float32'")
    return ctx


def device_name(context) -> str:
    """``"device (platform)"`` of the context's device, as reports name it."""
    d = context.devices[0]
    return f"{d.name.strip()} ({d.platform.name.strip()})"


def has_fp64(context) -> bool:
    """Whether the context's device has ``cl_khr_fp64`` (needed for ``precision="float64"``)."""
    return "cl_khr_fp64" in context.devices[0].extensions


def kernel_source(name: str, _seen: frozenset[str] = frozenset()) -> str:
    """Text of ``kernels/<name>`` with its ``#include "x.h"`` lines expanded from the same
    package, recursively, each header once."""
    pkg = resources.files(KERNEL_PACKAGE)
    text = pkg.joinpath(name).read_text(encoding="utf-8")
    seen = set(_seen | {name})

    def include(m: re.Match[str]) -> str:
        header = m.group(1)
        if header in seen:
            return f"// ---- {header} (already included)"
        seen.add(header)
        return f"// ---- {header}\n" + kernel_source(header, frozenset(seen))

    return re.sub(r'^\s*#include\s+"([^"]+)"\s*$', include, text, flags=re.MULTILINE)


def _options(defines: dict[str, object]) -> tuple[str, ...]:
    opts = []
    for k, v in sorted(defines.items()):
        if isinstance(v, float):
            v = repr(v)  # full float64 precision; the kernel casts to its own type
        opts.append(f"-D{k}={v}")
    return tuple(opts)


def precision_defines(precision: str) -> dict[str, object]:
    """The ``-D`` defines that select a kernel's arithmetic (``REAL_DOUBLE`` in
    kernels/real.h for float64)."""
    return {"REAL_DOUBLE": 1} if precision == "float64" else {}


def beam_series_defines() -> dict[str, object]:
    """``BEAM_TERMS``/``BEAM_SERIES``: the piston beam's power series
    (:func:`clsonar.physics.beam_series_coefficients`) that kernels/common.h evaluates."""
    from .physics import beam_series_coefficients

    coeffs = beam_series_coefficients(14)
    return {"BEAM_TERMS": len(coeffs),
            "BEAM_SERIES": "{" + ",".join(repr(float(v)) for v in coeffs) + "}"}


@cache
def kernel(program, name: str):
    """Kernel ``name`` of a built ``program`` (retrieved once: pyopencl's attribute access
    makes a new kernel object each time)."""
    return _cl().Kernel(program, name)


def max_work_group(kernel, device) -> int:
    """The largest work-group the device allows for ``kernel``."""
    return int(kernel.get_work_group_info(_cl().kernel_work_group_info.WORK_GROUP_SIZE, device))


@cache
def work_group(kernel, device, wanted: int) -> int:
    """A fixed work-group size for a 1-D kernel: ``wanted``, or the largest power of two the
    kernel allows below it — fixed because PoCL compiles a kernel anew for each work-group
    size it meets."""
    return max(1, min(wanted, 1 << (max_work_group(kernel, device).bit_length() - 1)))


def read_only_buffer(context, array: np.ndarray, dtype, empty_size: int = 1):
    """A read-only device copy of ``array`` as ``dtype`` (C order). OpenCL has no empty
    buffers: an empty array becomes ``empty_size`` zeros, which the kernels never read."""
    a = np.ascontiguousarray(array, dtype=dtype)
    if a.size == 0:
        a = np.zeros(empty_size, dtype=dtype)
    cl = _cl()
    return cl.Buffer(context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=a)


_PROGRAMS: dict[tuple, object] = {}


def build_program(context, name: str, defines: dict[str, object] | None = None):
    """Build ``kernels/<name>`` for ``context`` with ``-D`` ``defines``; memoised.

    A build failure raises :class:`DeviceError` naming the source file and the first
    compiler error; set ``PYOPENCL_COMPILER_OUTPUT=1`` for the full log.
    """
    options = _options(defines or {})
    key = (context, name, options)
    program = _PROGRAMS.get(key)
    if program is None:
        cl = _cl()
        try:
            program = _built(context, kernel_source(name), options)
        except cl.Error as e:
            first = next((ln for ln in str(e).splitlines() if "error" in ln.lower()), str(e))
            raise DeviceError(f"kernels/{name} failed to build on "
                              f"{context.devices[0].name.strip()}: {first.strip()[:200]}") from None
        _PROGRAMS[key] = program
    return program


def _built(context, source: str, options: tuple[str, ...]):
    """``source`` built for ``context``'s device with ``options``, from this machine's
    cache of built programs when it holds it (:func:`_cached_binary`): a build from
    source costs 40–80 ms even when the OpenCL driver caches it itself (PoCL still
    preprocesses and hashes the source), one from the driver's own binary about 5 ms. A
    binary the driver refuses is built again from source."""
    cl = _cl()
    device = context.devices[0]
    path = _cached_binary(device, source, options)
    with warnings.catch_warnings():
        if not os.environ.get("PYOPENCL_COMPILER_OUTPUT"):
            # NVIDIA's compiler logs on every build: pyopencl's warning of it would be
            # printed under every command's output; PYOPENCL_COMPILER_OUTPUT shows the log
            warnings.simplefilter("ignore", cl.CompilerWarning)
        if path is not None and path.is_file():
            try:
                return cl.Program(context, [device], [path.read_bytes()]).build(
                    options=list(options))
            except (cl.Error, OSError):
                pass
        program = cl.Program(context, source).build(options=list(options))
    if path is not None:
        _keep_binary(path, program.get_info(cl.program_info.BINARIES)[0])
    return program


#: Where built programs are kept (``$XDG_CACHE_HOME/clsonar/programs``, by default
#: ``~/.cache/clsonar/programs``); ``PYOPENCL_NO_CACHE`` (pyopencl's switch) turns it off.
PROGRAM_CACHE = "clsonar/programs"


def _cached_binary(device, source: str, options: tuple[str, ...]) -> Path | None:
    """The cache file of ``source`` built with ``options`` on ``device``: named by a hash of
    both and of everything that identifies the compiler (platform and device, their
    versions, the driver's, pyopencl's). None when caching is off."""
    if os.environ.get("PYOPENCL_NO_CACHE"):
        return None
    cl = _cl()
    platform = device.platform
    key = "\0".join((source, *options, platform.name, platform.version, device.name,
                     device.version, device.driver_version, cl.VERSION_TEXT))
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return root / PROGRAM_CACHE / f"{hashlib.sha256(key.encode()).hexdigest()}.bin"


def _keep_binary(path: Path, binary: bytes) -> None:
    """Write ``binary`` to the program cache; a cache that cannot be written is no error."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, binary)
    except OSError:
        pass
