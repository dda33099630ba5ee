"""The files a study writes (reports, data folders, verdicts, power tables): each through a
temporary of a unique name in its own folder, renamed over the old file only when written
whole. A full disk or an unwritable folder leaves the old file as it was, no 0-byte or cut
file, and an OSError naming the file (the command line prints it on one line)."""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator, Union

PathLike = Union[str, os.PathLike]


def check_folder(path: PathLike, what: str = "--out") -> Path:
    """ValueError when something other than a folder is at `path` (report --out /dev/full):
    said before any work is done."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise ValueError(f"{what}: {str(p)!r} is not a folder")
    return p


def folder(path: PathLike, what: str = "--out") -> Path:
    """`path` as an output folder, made where missing (check_folder first)."""
    p = check_folder(path, what)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OSError(e.errno, e.strerror, str(p)) from None
    return p


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextmanager
def replacing(path: PathLike) -> Iterator[Path]:
    """Yields a temporary path beside `path`, ending as `path` does (.png, .csv.gz: what
    matplotlib and pandas read the format from); when the block ends without an error the
    temporary replaces `path`, otherwise it is removed. A failure is an OSError naming `path`."""
    target = Path(path)
    suffix = "".join(target.suffixes[-2:])
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part" + suffix,
                                        dir=target.parent)
        os.close(fd)
    except OSError as e:
        raise OSError(e.errno, e.strerror, str(target)) from None
    tmp = Path(tmp_name)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())  # as a file written in place would have
        os.replace(tmp, target)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise OSError(e.errno, e.strerror, str(target)) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text(path: PathLike, text: str) -> None:
    with replacing(path) as tmp:
        tmp.write_text(text)


def to_csv(frame, path: PathLike, **kwargs) -> None:  # type: ignore[no-untyped-def]
    """DataFrame.to_csv through a temporary. pandas is handed the open temporary under the
    final name: a .gz header names the file it was written to, and the temporary's name would
    make the same data other bytes."""
    target = Path(path)
    with replacing(target) as tmp, open(tmp, "wb") as f:
        f.raw.name = target.name  # type: ignore[attr-defined]
        frame.to_csv(f, **kwargs)


def savefig(fig, path: PathLike, **kwargs) -> None:  # type: ignore[no-untyped-def]
    """Figure.savefig through a temporary."""
    with replacing(path) as tmp:
        fig.savefig(tmp, **kwargs)
