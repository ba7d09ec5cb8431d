# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Write report, plot and result files without ever following a symbolic link.

Policy (one place, used by every report and plot writer):

* The output directory named by the user (``--report DIR``, ``--plots DIR``, the directory of
  ``--estimates-out FILE``) must be a real directory: if it is a symbolic link it is refused
  (:class:`~rotor_estimator.core.errors.OutputError` naming the link and its target); a missing one
  is created (with its parents).
* Each file is written to a new temporary file in that directory (``O_CREAT | O_EXCL |
  O_NOFOLLOW``, relative to a descriptor of the directory opened with ``O_NOFOLLOW``) and then
  renamed over the final name with :func:`os.replace`. A rename replaces a directory entry; it
  never writes through it, so a symbolic link (or a hard link) already at the final name is
  replaced by the new regular file and the file it pointed to is left untouched. A warning on
  the ``rotor_estimator`` logger says so. Readers never see a half-written file.
* A directory at the final name is refused.
"""
from __future__ import annotations

import contextlib
import io
import logging
import os
import secrets
import stat
from pathlib import Path
from typing import IO, Any, Iterator

from rotor_estimator.core.errors import OutputError

__all__ = ["output_directory", "write_bytes", "write_text", "save_figure", "save_npz"]

_log = logging.getLogger("rotor_estimator")
_DIR_FD = os.open in os.supports_dir_fd and os.replace in os.supports_dir_fd and os.lstat in os.supports_dir_fd


def _link_text(path: Path) -> str:
    try:
        return os.readlink(path)
    except OSError:
        return "?"


def output_directory(path: str | Path, what: str = "output directory") -> Path:
    """Create ``path`` (and its parents) if missing and return it; refuse a symbolic link or a
    non-directory there. ``what`` names it in messages (e.g. ``--report``)."""
    p = Path(path)
    if p.is_symlink():
        raise OutputError(f"{what} {p}: is a symbolic link (to {_link_text(p)}); reports are written only into a "
                          f"real directory, never through a link: give the link's target as the directory")
    if p.exists() and not p.is_dir():
        raise OutputError(f"{what} {p}: exists and is not a directory")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{what} {p}: cannot create the directory ({exc.strerror or exc})") from None
    if p.is_symlink():  # created by someone else in between
        raise OutputError(f"{what} {p}: became a symbolic link while it was being created; refused")
    return p


@contextlib.contextmanager
def _atomic(path: str | Path) -> Iterator[IO[bytes]]:
    """A binary file object whose content replaces ``path`` when the block ends without error."""
    target = Path(path)
    parent = target.parent
    name = target.name
    if not name or name in (".", ".."):
        raise OutputError(f"cannot write {target}: not a file name")
    if parent.is_symlink():
        raise OutputError(f"cannot write {target}: its directory {parent} is a symbolic link (to "
                          f"{_link_text(parent)}); files are never written through a link")
    tmp = f".{name}.{secrets.token_hex(6)}.tmp"
    dfd = None
    try:
        if _DIR_FD:
            flags = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | getattr(os, "O_NOFOLLOW", 0)
            dfd = os.open(parent, flags)
            where = {"dir_fd": dfd}
        else:  # pragma: no cover - platforms without dir_fd (Windows)
            tmp = str(parent / tmp)
            where = {}
        try:
            st = os.lstat(name if dfd is not None else str(target), **where)
        except FileNotFoundError:
            st = None
        if st is not None and stat.S_ISDIR(st.st_mode):
            raise OutputError(f"cannot write {target}: a directory of that name exists")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
                     | getattr(os, "O_BINARY", 0), 0o666, **where)
        try:
            with os.fdopen(fd, "wb") as fh:
                yield fh
            if dfd is not None:
                os.replace(tmp, name, src_dir_fd=dfd, dst_dir_fd=dfd)
            else:  # pragma: no cover
                os.replace(tmp, target)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp, **where)
            raise
        if st is not None and stat.S_ISLNK(st.st_mode):
            _log.warning("replaced the symbolic link %s by a regular file; the file it pointed to was not "
                         "touched", target)
    except OSError as exc:
        if exc.errno is not None and exc.errno in (getattr(os, "ELOOP", -1), getattr(os, "ENOTDIR", -1)) \
                and parent.is_symlink():
            raise OutputError(f"cannot write {target}: its directory {parent} is a symbolic link; "
                              f"files are never written through a link") from None
        raise OutputError(f"cannot write {target}: {exc.strerror or exc}") from None
    finally:
        if dfd is not None:
            os.close(dfd)


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically, never through a symbolic link (module policy)."""
    with _atomic(path) as fh:
        fh.write(data)
    return Path(path)


def write_text(path: str | Path, text: str) -> Path:
    """:func:`write_bytes` of ``text`` as UTF-8."""
    return write_bytes(path, text.encode("utf-8"))


def save_figure(fig: Any, path: str | Path, **savefig_kwargs: Any) -> Path:
    """``fig.savefig`` into ``path`` under the module policy; the format follows the suffix (PNG default)."""
    fmt = Path(path).suffix.lstrip(".").lower() or "png"
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, **savefig_kwargs)  # rendered first: a failing plot leaves no file
    return write_bytes(path, buf.getvalue())


def save_npz(path: str | Path, **arrays: Any) -> Path:
    """``numpy.savez`` under the module policy; like numpy, adds ``.npz`` to a name without it."""
    import numpy as np

    p = Path(path)
    if p.suffix != ".npz":
        p = p.with_name(p.name + ".npz")
    with _atomic(p) as fh:
        np.savez(fh, **arrays)
    return p
