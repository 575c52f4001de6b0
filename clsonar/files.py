"""Files every part of clsonar reads and writes: text read with one clear error; files and
folders written whole or not at all (a temporary name, then a rename), rows appended whole
or not at all; a write that fails (a full disk, no permission) is one
:class:`~clsonar.errors.WriteError` line naming the path; and the folder of the bundled
scenes.

Temporary names are ``.NAME.clsonar-PID-XXXX`` beside ``NAME``: a writer killed before its
rename leaves one, and the next write of ``NAME`` removes it once ``PID`` is gone
(:func:`remove_stale`).
"""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
import threading
from collections.abc import Collection, Iterator, Mapping
from contextlib import contextmanager, suppress
from functools import cache
from importlib import resources
from pathlib import Path

from .errors import SceneError, WriteError

#: Largest text file read (scene files, sweep specs).
MAX_FILE_BYTES = 64 * 1024 * 1024


#: What ``clsonar run --png`` draws: nothing; the map stages (raw, filtered, thin: drawn
#: straight from the arrays, clsonar.pictures); or those and the plots with axes and
#: legends (scene, profile: matplotlib, when installed).
PNG_CHOICES = ("none", "stages", "all")

def read_text(path: str | os.PathLike[str], error: type[SceneError] = SceneError,
              max_bytes: int = MAX_FILE_BYTES) -> str:
    """The UTF-8 text of the file ``path`` (a BOM allowed); any problem — unreadable, larger
    than ``max_bytes``, not UTF-8 — raises ``error`` naming the file."""
    source = os.fspath(path)
    try:
        size = os.path.getsize(source)
        if size > max_bytes:
            raise error(f"file is {size} bytes, larger than the {max_bytes} bytes it may have",
                        source=source)
        with open(source, "rb") as f:
            raw = f.read()
    except OSError as e:
        raise error(f"cannot read file: {e.strerror or e}", source=source) from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise error(f"not UTF-8 text (byte {e.start})", source=source) from None


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


#: The process's umask, read once at import (os.umask can only be read by setting it).
_UMASK = _umask()
#: The permissions a plain ``open`` or ``mkdir`` gives (not a temporary one's 0600/0700).
FILE_MODE = 0o666 & ~_UMASK
FOLDER_MODE = 0o777 & ~_UMASK


@contextmanager
def writing(path: str | os.PathLike[str]) -> Iterator[None]:
    """Turn an :class:`OSError` raised inside the block into a :class:`WriteError` naming
    ``path`` (one line: ``PATH: cannot write: No space left on device``)."""
    try:
        yield
    except WriteError:
        raise
    except OSError as e:
        raise WriteError(path, e) from e


def _temp_prefix(name: str) -> str:
    """The start of every temporary name of a writer of ``name``: ``.NAME.clsonar-``."""
    return f".{name}.clsonar-"


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists (another user's counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _stale_pid(rest: str) -> bool:
    """Whether the temporary name's tail ``PID-XXXX`` is of a process that is gone."""
    pid = rest.partition("-")[0]
    return pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid))


def remove_stale(parent: str | os.PathLike[str], name: str) -> list[Path]:
    """Remove the temporary files and folders that writers of ``name`` in ``parent`` left
    when they were killed (their process is gone); returns what was removed."""
    prefix = _temp_prefix(name)
    try:
        entries = os.listdir(parent)
    except OSError:
        return []
    gone = [Path(parent, e) for e in entries
            if e.startswith(prefix) and _stale_pid(e[len(prefix):])]
    for path in gone:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
    return gone


def _write_fd(fd: int, data: bytes) -> None:
    """Write all of ``data`` to ``fd`` (``os.write`` again after a short write)."""
    view = memoryview(data)
    while view:
        written = os.write(fd, view)
        if written <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        view = view[written:]


def _write_new(folder: Path, files: Mapping[str, bytes]) -> None:
    """Create each file of ``files`` (name → bytes) in ``folder``, every one synced to the
    disk before this returns. The syncs run at once, each but the first in a thread of its
    own: they wait on the disk, not on Python, and the file system commits them together
    (the room's four outputs: 15-20 ms one after another, 5-10 ms at once)."""
    fds: list[int] = []
    failed: list[OSError] = []

    def sync(fd: int) -> None:
        try:
            os.fsync(fd)
        except OSError as e:
            failed.append(e)

    try:
        for name, data in files.items():
            fds.append(os.open(folder / name, os.O_WRONLY | os.O_CREAT | os.O_EXCL, FILE_MODE))
            _write_fd(fds[-1], data)
        threads = [threading.Thread(target=sync, args=(fd,)) for fd in fds[1:]]
        for thread in threads:
            thread.start()
        for fd in fds[:1]:
            sync(fd)
        for thread in threads:
            thread.join()
        if failed:
            raise failed[0]
    finally:
        for fd in fds:
            os.close(fd)


def write_atomic(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename,
    so readers never see a half-written file. The file gets the permissions a plain
    ``open`` would give it (0666 less the umask). A failure is a :class:`WriteError`,
    with ``path`` as it was."""
    path = Path(path)
    with writing(path):
        remove_stale(path.parent, path.name)
        fd, tmp = tempfile.mkstemp(dir=path.parent,
                                   prefix=f"{_temp_prefix(path.name)}{os.getpid()}-")
        try:
            try:
                os.fchmod(fd, FILE_MODE)
                _write_fd(fd, data)
                os.fsync(fd)
            finally:
                os.close(fd)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise


def append_whole(path: str | os.PathLike[str], data: bytes) -> None:
    """Append ``data`` to file ``path`` (created if need be), whole or not at all, durably:
    ``O_APPEND`` writes and an ``fsync``; after a failure (a full disk) the file is cut back
    to its length before and a :class:`WriteError` names it. Not for two writers at once."""
    with writing(path):
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, FILE_MODE)
        try:
            size = os.fstat(fd).st_size
            try:
                _write_fd(fd, data)
                os.fsync(fd)
            except BaseException:
                with suppress(OSError):
                    os.ftruncate(fd, size)
                raise
        finally:
            os.close(fd)


@cache
def _renameat2():
    """libc's ``renameat2`` (Linux), or None."""
    import ctypes

    try:
        return ctypes.CDLL(None, use_errno=True).renameat2
    except (AttributeError, OSError):
        return None


def exchange(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> None:
    """Swap the files or folders ``a`` and ``b`` in one atomic step (Linux ``renameat2``
    with ``RENAME_EXCHANGE``); where the system cannot, in three renames (``b`` briefly
    absent)."""
    at_cwd, rename_exchange = -100, 2
    fn = _renameat2()
    if fn is not None:
        import ctypes

        if fn(at_cwd, os.fsencode(a), at_cwd, os.fsencode(b), rename_exchange) == 0:
            return
        err = ctypes.get_errno()
        if err not in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP):
            raise OSError(err, os.strerror(err), os.fspath(b))
    side = Path(f"{os.fspath(a)}-swap")
    os.rename(b, side)
    os.rename(a, b)
    os.rename(side, a)


def _holds_cwd(folder: Path) -> bool:
    """Whether ``folder`` is the working folder or one above it."""
    try:
        cwd, target = Path.cwd().resolve(), folder.resolve()
    except OSError:
        return False
    return cwd == target or target in cwd.parents


#: Why a folder cannot be renamed or exchanged although it can be written in (a mount
#: point): its files are then replaced one by one.
_IN_PLACE = (errno.EBUSY, errno.EXDEV)


def _swap_in(tmp: Path, out: Path, owned: Collection[str]) -> bool:
    """Put folder ``tmp`` in the place of ``out`` in one step, when ``out`` is absent,
    empty or holds only ``owned`` names (the earlier outputs end up in ``tmp``); False,
    and nothing done, for any other ``out``."""
    if out.is_symlink() or _holds_cwd(out):
        return False
    try:
        os.rename(tmp, out)
        return True
    except OSError as e:
        if e.errno in _IN_PLACE:
            return False
        if e.errno not in (errno.EEXIST, errno.ENOTEMPTY):
            raise
    if not set(os.listdir(out)) <= set(owned):
        return False
    try:
        exchange(tmp, out)
    except OSError as e:
        if e.errno in _IN_PLACE:
            return False
        raise
    return True


@contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """An exclusive ``flock`` on ``folder`` for the block (one writer at a time)."""
    import fcntl

    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _replace_each(tmp: Path, out: Path, names: Collection[str],
                  owned: Collection[str]) -> None:
    """Move every file ``names`` from ``tmp`` into ``out`` and remove the ``owned`` ones
    they do not replace, one writer at a time."""
    with _locked(out):
        for name in names:
            os.replace(tmp / name, out / name)
        for name in set(owned) - set(names):
            (out / name).unlink(missing_ok=True)


def write_folder(out: str | os.PathLike[str], files: Mapping[str, bytes],
                 owned: Collection[str] = ()) -> None:
    """Write ``files`` (name → bytes) as the folder ``out``, whole or not at all.

    They are written and synced in a temporary folder beside ``out`` first. A new (or
    empty) ``out`` is that folder renamed; an ``out`` holding only ``owned`` names (an
    earlier run's outputs) is exchanged with it in one step: a reader, a killed writer or
    two writers at once leave one whole set, never a mix. In any other folder (other files
    beside ours, the working folder) the ``owned`` files are replaced one by one, one writer
    at a time. A failure is a :class:`WriteError` naming ``out``; nothing temporary stays.
    """
    out = Path(out)
    with writing(out):
        out.parent.mkdir(parents=True, exist_ok=True)
        remove_stale(out.parent, out.name)
        tmp = Path(tempfile.mkdtemp(prefix=f"{_temp_prefix(out.name)}{os.getpid()}-",
                                    dir=out.parent))
        try:
            _write_new(tmp, files)
            os.chmod(tmp, FOLDER_MODE)
            if not _swap_in(tmp, out, owned):
                _replace_each(tmp, out, list(files), owned)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


def bundled_scenes() -> Path:
    """The folder of the bundled scenes (``scenes/``, installed as ``clsonar.scenes``)."""
    return Path(str(resources.files("clsonar.scenes")))
