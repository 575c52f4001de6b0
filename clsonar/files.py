"""Files every part of clsonar reads and writes: text read with one clear error, outputs
written atomically, and the folder of the bundled scenes."""

from __future__ import annotations

import os
import tempfile
from importlib import resources
from pathlib import Path

from .errors import SceneError

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


def write_atomic(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename,
    so readers never see a half-written file. The file gets the permissions a plain
    ``open`` would give it (0666 less the umask), not the temporary file's 0600."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def bundled_scenes() -> Path:
    """The folder of the bundled scenes (``scenes/``, installed as ``clsonar.scenes``)."""
    return Path(str(resources.files("clsonar.scenes")))
