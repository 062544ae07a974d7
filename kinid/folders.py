"""Folders written whole or not at all: a staged sibling folder swapped in, one writer at a time."""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from .files import _inside

__all__ = ["staged_folder", "check_output_folder", "listed_folder", "check_listed_folder", "not_listed", "LIST_NAME"]


#: Names of what :func:`staged_folder` keeps beside the folder ``DIR`` while it writes it:
#: ``.DIR.kinid-lock`` (the lock of one writer at a time), ``.DIR.kinid-new-XXXXXXXX`` (the folder being
#: written; after the swap, the earlier result being removed) and, where the file system cannot swap
#: two folders in one step, ``.DIR.kinid-old-XXXXXXXX`` (the earlier result set aside). A run killed
#: at any moment may leave a ``-new-`` or ``-old-`` folder; the next run into ``DIR`` removes it.
STAGE_TAG, ASIDE_TAG, LOCK_TAG = ".kinid-new-", ".kinid-old-", ".kinid-lock"


@contextlib.contextmanager
def staged_folder(path, *, foreign=None):
    """Write a folder whole or not at all: yield a fresh folder beside ``path``, then swap it in.

    The body writes every file into the yielded folder. On success that folder takes the place of
    ``path`` in one step (a swap of the two folders where the file system has it, else two renames),
    and the earlier folder is removed: a process killed at any moment leaves at ``path`` either the
    earlier result or the new one, whole (plus, at worst, a ``.NAME.kinid-new-…`` folder beside it
    that the next run removes). If the body raises — an error, Ctrl-C — the new folder is removed
    and ``path`` is left as it was.

    One writer at a time: a second one gets a DataError while the first holds the lock (a file
    ``.NAME.kinid-lock`` beside the folder). Only a folder that does not exist, is empty or holds
    nothing ``foreign`` says is not the command's own is replaced: ``--out ~/Documents`` never
    deletes the user's files.

    Parameters
    ----------
    path : str or Path
        The folder to write (created with its parents if missing). A symbolic link to a folder
        stays a link: the folder it points to is written.
    foreign : callable (Path) -> list of str, optional
        The names in an existing, non-empty folder that are not an earlier result of the command
        (it may then be replaced only if the list is empty). Default: every name (only an empty
        folder is replaced).

    Raises
    ------
    DataError
        Naming the folder or the file: a file where the folder should be, a read-only folder, a
        folder holding files the command did not write, another writer, and every OSError while
        writing (a full disk, no permission, a read-only file system).

    Examples
    --------
    >>> with staged_folder("tables") as d:   # doctest: +SKIP
    ...     write_text(d / "X.csv", "x,EXX_um\\n0,0\\n")
    """
    from .errors import DataError, KinidError

    shown = str(path)
    if not shown.strip() or shown == "-":
        raise DataError("the output folder is empty; give a folder to write")
    target = Path(os.path.abspath(path))
    if os.path.islink(target):
        target = Path(os.path.realpath(target))
    if not target.name:
        raise DataError("cannot replace the root folder; give a folder to write", path=shown)
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DataError(f"cannot create the folder {str(parent)!r} ({exc.strerror or exc})", path=shown) from None
    with _folder_lock(target, shown):
        _clean_leftovers(target)
        _check_replaceable(target, shown, foreign)
        try:
            mode = os.stat(target).st_mode & 0o7777
        except OSError:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o777 & ~umask
        try:
            staged = Path(tempfile.mkdtemp(prefix=f".{target.name}{STAGE_TAG}", dir=parent))
        except OSError as exc:
            raise DataError(f"cannot write in folder {str(parent)!r} ({exc.strerror or exc})", path=shown) from None
        try:
            try:
                os.chmod(staged, mode)
                yield staged
            except OSError as exc:
                where = _shown_name(exc.filename, staged, shown) if exc.filename else shown
                raise DataError(f"cannot write ({exc.strerror or exc})", path=where) from None
            except KinidError as exc:
                raise _renamed_path(exc, staged, shown) from None
            _check_replaceable(target, shown, foreign)  # nothing put in meanwhile
            _fsync_folder(staged)
            try:
                earlier = _swap(staged, target)
            except OSError as exc:
                raise DataError(f"cannot put the new folder in place ({exc.strerror or exc})", path=shown) from None
            _fsync_folder(parent)
        except BaseException:
            _remove_tree(staged)
            raise
        if earlier is not None:
            _remove_tree(earlier)


#: The file in which a folder written by :func:`listed_folder` lists its own files (what a later run may replace).
LIST_NAME = "kinid-files.json"


@contextlib.contextmanager
def listed_folder(path, *, written_by: str):
    """:func:`staged_folder` for a folder of a command's files (tables, rendered frames, the demo's run).

    When the body has written its files, the folder is given ``kinid-files.json`` listing them and the
    command (``written_by``); a later run replaces the folder only if it holds nothing else
    (:func:`not_listed`). A folder of the user's files is never replaced.

    Examples
    --------
    >>> with listed_folder("tables", written_by="kinid uvw --tables") as d:   # doctest: +SKIP
    ...     write_text(d / "U.csv", text)
    """
    from .files import write_json

    with staged_folder(path, foreign=not_listed) as stage:
        yield stage
        write_json(stage / LIST_NAME, {"written_by": written_by, "files": sorted(os.listdir(stage))}, indent=1)


def check_listed_folder(path) -> None:
    """Refuse early what :func:`listed_folder` would refuse to replace (before the command's work)."""
    check_output_folder(path, foreign=not_listed)


def not_listed(folder) -> list:
    """Names in ``folder`` that its ``kinid-files.json`` does not list (every name where there is no such list).

    The ``foreign=`` of :func:`listed_folder`: links are never the command's own.
    """
    from .errors import KinidError
    from .files import read_json
    from .schema import Fields, Items, Text, validate

    folder = Path(folder)
    names = sorted(os.listdir(folder))
    marker = folder / LIST_NAME
    if marker.is_symlink() or not marker.is_file():
        return names
    try:
        own = validate(read_json(marker, what="list of files"), Fields({"files": Items(Text())}, other=True))["files"]
    except KinidError:
        return names
    own = set(own) | {LIST_NAME}
    return [n for n in names if n not in own or (folder / n).is_symlink()]


def _shown_name(name, staged: Path, shown: str) -> str:
    """``name`` inside the staged folder as the user's spelling of the target folder."""
    name = os.fsdecode(name)
    rel = os.path.relpath(name, staged) if _inside(Path(name), staged) else None
    return name if rel is None else (shown if rel == "." else os.path.join(shown, rel))


def _renamed_path(exc, staged: Path, shown: str):
    """``exc`` naming the target folder where it names the staged one."""
    if exc.path is None or not _inside(Path(exc.path), staged):
        return exc
    try:
        new = type(exc)(exc.message.replace(str(staged), shown), path=_shown_name(exc.path, staged, shown),
                        line=exc.line, column=exc.column, parameter=exc.parameter)
    except TypeError:  # pragma: no cover - a subclass with another signature
        return exc
    return new


@contextlib.contextmanager
def _folder_lock(target: Path, shown: str):
    """Hold ``.NAME.kinid-lock`` beside ``target`` (non-blocking); removed when released."""
    from .errors import DataError

    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield
        return
    lock = target.parent / f".{target.name}{LOCK_TAG}"
    while True:
        try:
            try:
                fd = os.open(lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
            except PermissionError:
                if not os.path.isfile(lock):
                    raise
                fd = os.open(lock, os.O_RDONLY | getattr(os, "O_CLOEXEC", 0))  # another user's: a lock needs no write
        except OSError as exc:
            raise DataError(f"cannot write in folder {str(target.parent)!r} ({exc.strerror or exc})",
                            path=shown) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise DataError("another kinid is writing this folder; wait until it has finished, or choose another "
                            "folder", path=shown) from None
        except OSError as exc:
            os.close(fd)
            raise DataError(f"cannot lock the folder for writing ({exc.strerror or exc})", path=shown) from None
        # the writer before may have removed the lock file between our open and our lock: lock the file in place
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except OSError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(lock)
        os.close(fd)


def _leftovers(target: Path) -> list:
    """(kind, path) of the ``-new-`` and ``-old-`` folders an interrupted run left beside ``target``."""
    import re

    pattern = re.compile(rf"\.{re.escape(target.name)}\.kinid-(new|old)-[a-z0-9_]{{8}}")
    found = []
    try:
        entries = list(os.scandir(target.parent))
    except OSError:
        return found
    for e in entries:
        m = pattern.fullmatch(e.name)
        if m and e.is_dir(follow_symlinks=False):
            found.append((m.group(1), Path(e.path)))
    return found


def _clean_leftovers(target: Path) -> None:
    """Remove what a killed run left beside ``target``; put back an earlier result set aside (two renames)."""
    found = _leftovers(target)
    if not os.path.lexists(target):
        aside = sorted((p for kind, p in found if kind == "old"), key=lambda p: os.stat(p).st_mtime)
        if aside:
            with contextlib.suppress(OSError):
                os.rename(aside[-1], target)
    for _, p in found:
        if os.path.lexists(p):
            _remove_tree(p)


def check_output_folder(path, *, foreign=None) -> None:
    """Refuse early what :func:`staged_folder` would refuse to replace (a file, a read-only folder, a folder
    holding what ``foreign`` names), before a command spends its time computing what to write."""
    target = Path(os.path.abspath(path))
    if os.path.islink(target):
        target = Path(os.path.realpath(target))
    _check_replaceable(target, str(path), foreign)


def _check_replaceable(target: Path, shown: str, foreign) -> None:
    """Refuse to replace a file, a read-only folder or a folder holding what the command did not write."""
    import stat

    from .errors import DataError

    try:
        st = os.lstat(target)
    except FileNotFoundError:
        return
    except OSError as exc:
        raise DataError(f"cannot use as output folder ({exc.strerror or exc})", path=shown) from None
    if not stat.S_ISDIR(st.st_mode):
        raise DataError("is a file, not a folder; give a folder to write", path=shown)
    if os.path.ismount(target):
        raise DataError("is the top folder of a disk (a mount point), which kinid cannot replace whole: give a "
                        "folder inside it", path=shown)
    if not os.access(target, os.W_OK | os.X_OK):
        raise DataError("the folder is read-only; kinid writes the whole folder anew: make it writable or "
                        "choose another folder", path=shown)
    try:
        names = sorted(os.listdir(target))
    except OSError as exc:
        raise DataError(f"cannot read the folder ({exc.strerror or exc})", path=shown) from None
    if not names:
        return
    bad = sorted(foreign(target)) if foreign is not None else names
    if bad:
        listed = ", ".join(bad[:3]) + (f" and {len(bad) - 3} more" if len(bad) > 3 else "")
        raise DataError(f"holds what is not an earlier result of this command ({listed}); kinid replaces the whole "
                        f"folder, so it writes only into a new or empty folder or over its own earlier result: "
                        f"choose another folder", path=shown)


def _exchange(a: Path, b: Path) -> bool:
    """Swap two folders in one step (Linux renameat2 RENAME_EXCHANGE); False where there is no such call."""
    import sys

    if not sys.platform.startswith("linux"):
        return False
    import ctypes
    import errno

    try:
        call = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    call.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    call.restype = ctypes.c_int
    at_fdcwd, rename_exchange = -100, 2
    if call(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP, getattr(errno, "ENOTSUP", errno.EOPNOTSUPP)):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _swap(staged: Path, target: Path):
    """Put ``staged`` at ``target``; the path that now holds the earlier folder, or None."""
    import secrets

    if not os.path.lexists(target):
        os.rename(staged, target)
        return None
    if _exchange(staged, target):
        return staged
    aside = target.parent / f".{target.name}{ASIDE_TAG}{secrets.token_hex(4)}"
    os.rename(target, aside)
    try:
        os.rename(staged, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.rename(aside, target)
        raise
    return aside


def _remove_tree(path: Path) -> None:
    import shutil

    shutil.rmtree(path, ignore_errors=True)


def _fsync_folder(path: Path) -> None:
    """Make a folder's entries durable (where the system allows a folder to be synced)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
