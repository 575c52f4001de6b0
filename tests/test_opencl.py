"""Programs kept built between processes (clsonar.opencl's program cache, issue 16): a
program loaded from the cache computes what one built from source does; a damaged cache
file is built again from source; PYOPENCL_NO_CACHE writes nothing."""

import numpy as np
import pytest

from clsonar import opencl

cl = pytest.importorskip("pyopencl")

SOURCE = "__kernel void twice(__global float *a) { a[get_global_id(0)] *= TIMES; }"
OPTIONS = ("-DTIMES=2.0f",)


@pytest.fixture
def context():
    try:
        return opencl.get_context()
    except Exception as e:  # pragma: no cover - depends on the machine
        pytest.skip(f"no OpenCL device: {e}")


def _doubled(context, program) -> np.ndarray:
    a = np.arange(8, dtype=np.float32)
    buf = cl.Buffer(context, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR, hostbuf=a)
    queue = opencl.queue(context)
    cl.Kernel(program, "twice")(queue, a.shape, None, buf)
    cl.enqueue_copy(queue, a, buf)
    return a


def _cached(context) -> list:
    device = context.devices[0]
    path = opencl._cached_binary(device, SOURCE, OPTIONS)
    return [] if path is None or not path.exists() else [path]


def test_a_program_is_kept_built_and_loaded_from_the_cache(context, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.delenv("PYOPENCL_NO_CACHE", raising=False)
    assert _cached(context) == []
    first = opencl._built(context, SOURCE, OPTIONS)
    [path] = _cached(context)
    assert path.parent == tmp_path / opencl.PROGRAM_CACHE
    again = opencl._built(context, SOURCE, OPTIONS)
    np.testing.assert_array_equal(_doubled(context, again), 2 * np.arange(8))
    np.testing.assert_array_equal(_doubled(context, first), _doubled(context, again))
    other = opencl._cached_binary(context.devices[0], SOURCE, ("-DTIMES=3.0f",))
    assert other != path  # options are part of the key


def test_a_damaged_cache_file_is_built_again(context, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.delenv("PYOPENCL_NO_CACHE", raising=False)
    path = opencl._cached_binary(context.devices[0], SOURCE, OPTIONS)
    path.parent.mkdir(parents=True)
    path.write_bytes(b"not a program")
    program = opencl._built(context, SOURCE, OPTIONS)
    np.testing.assert_array_equal(_doubled(context, program), 2 * np.arange(8))
    assert path.read_bytes() != b"not a program"


def test_no_cache_with_pyopencl_no_cache(context, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setenv("PYOPENCL_NO_CACHE", "1")
    opencl._built(context, SOURCE, OPTIONS)
    assert not (tmp_path / opencl.PROGRAM_CACHE).exists()


def test_a_compiler_log_is_no_warning_unless_asked_for(context, tmp_path, monkeypatch):
    """On an NVIDIA H200 every build logs something, and pyopencl's CompilerWarning of it
    was printed under every command's output (seen by the GPU run of issue 16): a build
    warns only with ``PYOPENCL_COMPILER_OUTPUT`` set, which asks for the log."""
    import warnings

    monkeypatch.setenv("PYOPENCL_NO_CACHE", "1")
    monkeypatch.delenv("PYOPENCL_COMPILER_OUTPUT", raising=False)
    noisy = '#warning "a compiler log"\n' + SOURCE
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        program = opencl._built(context, noisy, OPTIONS)
    assert not [w for w in caught if issubclass(w.category, cl.CompilerWarning)]
    np.testing.assert_array_equal(_doubled(context, program), 2 * np.arange(8))
    monkeypatch.setenv("PYOPENCL_COMPILER_OUTPUT", "1")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # another source: NVIDIA's driver's own cache logs nothing
        opencl._built(context, noisy + "// asked for its log\n", OPTIONS)
    assert [w for w in caught if issubclass(w.category, cl.CompilerWarning)]
